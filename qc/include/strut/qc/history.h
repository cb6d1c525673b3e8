// The QC history (docs/qc.md): every decision (serial, time, session, reference, verdict, reasons
// and every quantity), queried by serial and date, in an embedded SQLite file or on a PostgreSQL
// server that every rig of a line shares; the same schema, versions and migrations on both.
#pragma once

#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "strut/qc/decision.h"


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
  std::string key;  //!< unique per decision (History::Record)
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

//! The schema this strut writes; older ones are migrated when opened, newer ones refused.
inline constexpr int kHistorySchemaVersion = 2;

//! What Record did.
struct Recorded {
  long id = 0;          //!< the decision's id
  bool inserted = true;  //!< false: a decision with its key was there already (and was kept)
};

class HistoryStore;

class History {
 public:
  //! Opens the history at `location`: a PostgreSQL URL (postgresql://USER@HOST:PORT/DB or
  //! postgres://..., libpq's form; the password from PGPASSWORD, ~/.pgpass or a service file), or
  //! else an SQLite file (created when missing). Creates or migrates the tables. Throws
  //! HistoryError naming the location (never its password): not a database, no server, a URL that
  //! holds a password, a schema newer than this strut's.
  explicit History(const std::string& location);
  ~History();
  History(const History&) = delete;
  History& operator=(const History&) = delete;

  //! Stores a decision at `time` (UTC ISO 8601, "2026-12-02T04:50:00Z"; empty: now) under `key`
  //! (empty: a new random key). One transaction: a decision is stored whole or not at all; a
  //! decision whose key is stored already is not stored again (a batch's shard run twice). A
  //! transaction lost to another writer is run again. A malformed `time` throws
  //! std::invalid_argument before anything is written; a lost server throws HistoryError.
  Recorded Record(const Decision& decision, const std::string& time = "", const std::string& key = "");

  //! Decisions in time order, optionally of one serial and at or after `since` (a date
  //! "2026-12-01" or an ISO time).
  std::vector<HistoryEntry> Query(const std::optional<std::string>& serial = std::nullopt,
                                  const std::optional<std::string>& since = std::nullopt) const;

  //! The location in messages and logs (a URL without its password).
  const std::string& where() const;
  int schema_version() const { return version_; }

 private:
  void Migrate();
  std::unique_ptr<HistoryStore> store_;
  int version_ = 0;
};

//! True for a PostgreSQL URL (postgresql:// or postgres://).
bool IsPostgresUrl(const std::string& location);
//! `location` with any password taken out (user:secret@ becomes user@, password=... is dropped).
std::string RedactedLocation(const std::string& location);

//! Per quantity over `entries` (time order).
std::vector<QuantityTrend> Trends(const std::vector<HistoryEntry>& entries);

//! True for a UTC time "YYYY-MM-DDTHH:MM:SSZ" (what Record stores).
bool IsUtcTime(const std::string& text);

}  // namespace strut::qc
