#include "strut/qc/history.h"

#include <fmt/format.h>
#include <sqlite3.h>

#include <cmath>
#include <ctime>
#include <map>
#include <nlohmann/json.hpp>
#include <regex>

#include "strut/daq/session.h"

namespace strut::qc {
namespace {

constexpr const char* kSchema = R"(
CREATE TABLE IF NOT EXISTS decisions (
  id INTEGER PRIMARY KEY,
  serial TEXT NOT NULL,
  time TEXT NOT NULL,            -- UTC ISO 8601
  session TEXT,
  reference TEXT,
  model TEXT,
  verdict TEXT NOT NULL,         -- PASS, FAIL, UNDECIDED
  reasons TEXT                   -- JSON array of strings
);
CREATE TABLE IF NOT EXISTS quantities (
  decision INTEGER NOT NULL REFERENCES decisions(id),
  name TEXT NOT NULL, unit TEXT, value REAL, sd REAL, nominal REAL, lower REAL, upper REAL,
  status TEXT, meaning TEXT
);
CREATE INDEX IF NOT EXISTS decisions_by_serial ON decisions(serial, time);
CREATE INDEX IF NOT EXISTS quantities_by_decision ON quantities(decision);
)";

//! A prepared statement that finalises itself.
class Statement {
 public:
  Statement(sqlite3* db, const std::string& sql, const std::string& path) : db_(db), path_(path) {
    if (sqlite3_prepare_v2(db, sql.c_str(), -1, &stmt_, nullptr) != SQLITE_OK)
      throw HistoryError(fmt::format("{}: {}", path, sqlite3_errmsg(db)));
  }
  ~Statement() { sqlite3_finalize(stmt_); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  void Bind(int i, const std::string& v) { Check(sqlite3_bind_text(stmt_, i, v.c_str(), -1, SQLITE_TRANSIENT)); }
  void Bind(int i, double v) { Check(std::isfinite(v) ? sqlite3_bind_double(stmt_, i, v) : sqlite3_bind_null(stmt_, i)); }
  void Bind(int i, long v) { Check(sqlite3_bind_int64(stmt_, i, v)); }
  //! True while there is a row.
  bool Step() {
    const int rc = sqlite3_step(stmt_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    throw HistoryError(fmt::format("{}: {}", path_, sqlite3_errmsg(db_)));
  }
  std::string Text(int col) const {
    const unsigned char* t = sqlite3_column_text(stmt_, col);
    return t ? reinterpret_cast<const char*>(t) : "";
  }
  double Real(int col) const { return sqlite3_column_type(stmt_, col) == SQLITE_NULL ? NAN : sqlite3_column_double(stmt_, col); }
  long Int(int col) const { return sqlite3_column_int64(stmt_, col); }

 private:
  void Check(int rc) {
    if (rc != SQLITE_OK) throw HistoryError(fmt::format("{}: {}", path_, sqlite3_errmsg(db_)));
  }
  sqlite3* db_;
  sqlite3_stmt* stmt_ = nullptr;
  std::string path_;
};

Status ParseStatus(const std::string& s) {
  for (Status x : {Status::kIn, Status::kOut, Status::kGuardBand, Status::kUndetermined, Status::kUntoleranced})
    if (s == ToString(x)) return x;
  return Status::kUndetermined;
}

//! Days since the epoch of an ISO 8601 UTC time ("2026-12-02T04:50:00Z" or a date); NaN if unreadable.
double Days(const std::string& iso) {
  std::tm tm{};
  if (sscanf(iso.c_str(), "%d-%d-%dT%d:%d:%d", &tm.tm_year, &tm.tm_mon, &tm.tm_mday, &tm.tm_hour, &tm.tm_min,
             &tm.tm_sec) < 3)
    return NAN;
  tm.tm_year -= 1900;
  tm.tm_mon -= 1;
  return static_cast<double>(timegm(&tm)) / 86400.0;
}

}  // namespace

bool IsUtcTime(const std::string& text) {
  return std::regex_match(text, std::regex(R"(\d{4}-\d{2}-\d{2}T\d{2}:\d{2}:\d{2}Z)"));
}

History::History(const std::string& path) : path_(path) {
  if (sqlite3_open_v2(path.c_str(), &db_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, nullptr) != SQLITE_OK) {
    const std::string why = db_ ? sqlite3_errmsg(db_) : "out of memory";
    sqlite3_close(db_);
    db_ = nullptr;
    throw HistoryError(fmt::format("{}: cannot open the QC history: {}", path, why));
  }
  sqlite3_busy_timeout(db_, 5000);  // another station writing: wait up to 5 s, then fail with the file's name
  try {
    Exec(kSchema);
  } catch (const HistoryError& e) {
    sqlite3_close(db_);
    db_ = nullptr;
    throw HistoryError(fmt::format("{} (is it a strut QC history?)", e.what()));
  }
}

History::~History() { sqlite3_close(db_); }

void History::Exec(const std::string& sql) const {
  char* error = nullptr;
  if (sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &error) != SQLITE_OK) {
    const std::string why = error ? error : "unknown error";
    sqlite3_free(error);
    throw HistoryError(fmt::format("{}: {}", path_, why));
  }
}

long History::Record(const Decision& d, const std::string& time) {
  if (!time.empty() && !IsUtcTime(time))
    throw std::invalid_argument("the decision's time '" + time + "' is not a UTC time YYYY-MM-DDTHH:MM:SSZ");
  Exec("BEGIN IMMEDIATE");
  try {
    Statement s(db_,
                "INSERT INTO decisions (serial, time, session, reference, model, verdict, reasons) VALUES (?,?,?,?,?,?,?)",
                path_);
    s.Bind(1, d.serial);
    s.Bind(2, time.empty() ? daq::UtcNowIso8601() : time);
    s.Bind(3, d.session);
    s.Bind(4, d.reference);
    s.Bind(5, d.model);
    s.Bind(6, std::string(ToString(d.verdict)));
    s.Bind(7, nlohmann::json(d.reasons).dump());
    s.Step();
    const long id = sqlite3_last_insert_rowid(db_);
    for (const QuantityDecision& q : d.quantities) {
      Statement r(db_,
                  "INSERT INTO quantities (decision, name, unit, value, sd, nominal, lower, upper, status, meaning) "
                  "VALUES (?,?,?,?,?,?,?,?,?,?)",
                  path_);
      r.Bind(1, id);
      r.Bind(2, q.quantity.name);
      r.Bind(3, q.quantity.unit);
      r.Bind(4, q.quantity.value);
      r.Bind(5, q.quantity.sd);
      r.Bind(6, q.nominal);
      r.Bind(7, q.lower);
      r.Bind(8, q.upper);
      r.Bind(9, std::string(ToString(q.status)));
      r.Bind(10, q.meaning);
      r.Step();
    }
    Exec("COMMIT");
    return id;
  } catch (...) {  // whatever failed, the transaction is undone and the error goes on to the caller
    sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
    throw;
  }
}

std::vector<HistoryEntry> History::Query(const std::optional<std::string>& serial,
                                         const std::optional<std::string>& since) const {
  if (since && !std::regex_match(*since, std::regex(R"(\d{4}-\d{2}-\d{2}(T\d{2}:\d{2}(:\d{2})?Z?)?)")))
    throw std::invalid_argument("--since '" + *since + "': give a date YYYY-MM-DD or a UTC time YYYY-MM-DDTHH:MM:SSZ");
  std::string sql = "SELECT id, serial, time, session, reference, model, verdict, reasons FROM decisions WHERE 1";
  if (serial) sql += " AND serial = ?1";
  if (since) sql += " AND time >= ?2";
  sql += " ORDER BY time, id";
  Statement s(db_, sql, path_);
  if (serial) s.Bind(1, *serial);
  if (since) s.Bind(2, *since);
  std::vector<HistoryEntry> out;
  std::map<long, std::size_t> at;
  while (s.Step()) {
    HistoryEntry e;
    e.id = s.Int(0);
    e.serial = s.Text(1);
    e.time = s.Text(2);
    e.session = s.Text(3);
    e.reference = s.Text(4);
    e.model = s.Text(5);
    e.verdict = s.Text(6);
    try {
      e.reasons = nlohmann::json::parse(s.Text(7)).get<std::vector<std::string>>();
    } catch (const nlohmann::json::exception&) {  // a row written by hand: its text is the one reason
      e.reasons = {s.Text(7)};
    }
    at[e.id] = out.size();
    out.push_back(std::move(e));
  }
  Statement q(db_,
              "SELECT decision, name, unit, value, sd, nominal, lower, upper, status, meaning FROM quantities "
              "ORDER BY rowid",
              path_);
  while (q.Step()) {
    const auto it = at.find(q.Int(0));
    if (it == at.end()) continue;
    QuantityDecision d;
    d.quantity.name = q.Text(1);
    d.quantity.unit = q.Text(2);
    d.quantity.value = q.Real(3);
    d.quantity.sd = q.Real(4);
    d.nominal = q.Real(5);
    d.lower = q.Real(6);
    d.upper = q.Real(7);
    d.status = ParseStatus(q.Text(8));
    d.meaning = q.Text(9);
    out[it->second].quantities.push_back(std::move(d));
  }
  return out;
}

std::vector<QuantityTrend> Trends(const std::vector<HistoryEntry>& entries) {
  std::vector<QuantityTrend> trends;
  std::map<std::string, std::vector<std::pair<double, double>>> points;  // name: (day, value)
  std::map<std::string, std::size_t> at;
  for (const HistoryEntry& e : entries)
    for (const QuantityDecision& q : e.quantities) {
      if (!at.count(q.quantity.name)) {
        at[q.quantity.name] = trends.size();
        trends.push_back({q.quantity.name, q.quantity.unit});
      }
      QuantityTrend& t = trends[at[q.quantity.name]];
      if (q.status == Status::kOut || q.status == Status::kGuardBand) ++t.out_of_band;
      if (std::isfinite(q.quantity.value)) points[q.quantity.name].push_back({Days(e.time), q.quantity.value});
    }
  for (QuantityTrend& t : trends) {
    const auto& p = points[t.name];
    t.count = static_cast<long>(p.size());
    if (p.empty()) continue;
    double sum = 0, sq = 0, tmin = p.front().first, tmax = p.front().first;
    t.min = t.max = p.front().second;
    for (const auto& [day, v] : p) {
      sum += v;
      t.min = std::min(t.min, v);
      t.max = std::max(t.max, v);
      tmin = std::min(tmin, day);
      tmax = std::max(tmax, day);
    }
    t.mean = sum / p.size();
    for (const auto& [day, v] : p) sq += (v - t.mean) * (v - t.mean);
    t.sd = p.size() > 1 ? std::sqrt(sq / (p.size() - 1)) : NAN;
    t.first = p.front().second;
    t.last = p.back().second;
    if (p.size() > 1 && tmax > tmin) {
      double md = 0;
      for (const auto& pt : p) md += pt.first / p.size();
      double sxy = 0, sxx = 0;
      for (const auto& [day, v] : p) {
        sxy += (day - md) * (v - t.mean);
        sxx += (day - md) * (day - md);
      }
      t.slope_per_day = sxy / sxx;
    }
  }
  return trends;
}

}  // namespace strut::qc
