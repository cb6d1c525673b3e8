// The QC history (docs/qc.md): every decision in an embedded SQLite database (serial, time,
// session, reference, verdict, reasons and every quantity), queried by serial and date.
#pragma once

#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "strut/qc/decision.h"

struct sqlite3;

namespace strut::qc {

//! A database that cannot be opened, created or written; the message names the file.
class HistoryError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

//! One stored decision.
struct HistoryEntry {
  long id = 0;
  std::string serial, time, session, reference, verdict, model;  //!< time: UTC ISO 8601
  std::vector<std::string> reasons;
  std::vector<QuantityDecision> quantities;  //!< quantity (name, unit, value, sd), band, status, meaning
};

//! Trend of one quantity over a selection of decisions, in time order.
struct QuantityTrend {
  std::string name, unit;
  long count = 0;
  double mean = NAN, sd = NAN, min = NAN, max = NAN, first = NAN, last = NAN;
  //! Least-squares slope over time, per day (NaN with fewer than two distinct times).
  double slope_per_day = NAN;
  long out_of_band = 0;  //!< decisions in which it was out or in its guard band
};

class History {
 public:
  //! Opens (creating when missing) the database at `path` and its tables. Throws HistoryError
  //! naming the file when it is not an SQLite database or cannot be created.
  explicit History(const std::string& path);
  ~History();
  History(const History&) = delete;
  History& operator=(const History&) = delete;

  //! Stores a decision at `time` (UTC ISO 8601, "2026-12-02T04:50:00Z"; empty: now); returns its id.
  //! One transaction: a decision is stored whole or not at all. A malformed `time` throws
  //! std::invalid_argument before anything is written.
  long Record(const Decision& decision, const std::string& time = "");

  //! Decisions in time order, optionally of one serial and at or after `since` (a date
  //! "2026-12-01" or an ISO time).
  std::vector<HistoryEntry> Query(const std::optional<std::string>& serial = std::nullopt,
                                  const std::optional<std::string>& since = std::nullopt) const;

 private:
  void Exec(const std::string& sql) const;
  std::string path_;
  sqlite3* db_ = nullptr;
};

//! Per quantity over `entries` (time order).
std::vector<QuantityTrend> Trends(const std::vector<HistoryEntry>& entries);

//! True for a UTC time "YYYY-MM-DDTHH:MM:SSZ" (what Record stores).
bool IsUtcTime(const std::string& text);

}  // namespace strut::qc
