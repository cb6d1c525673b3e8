#include "strut/qc/history.h"

#include <fmt/format.h>

#include <cmath>
#include <ctime>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <regex>
#include <thread>
#include <chrono>
#include <cstdlib>

#include "history_store.h"
#include "strut/daq/session.h"

namespace strut::qc {
namespace {

//! The tables of schema version 2 (version 1, the first, had no decision_key); `id` in the
//! database's own words.
std::string Tables(const std::string& id) {
  return fmt::format(R"(
CREATE TABLE IF NOT EXISTS decisions (
  {},
  serial TEXT NOT NULL,
  time TEXT NOT NULL,            -- UTC ISO 8601
  session TEXT,
  reference TEXT,
  model TEXT,
  verdict TEXT NOT NULL,         -- PASS, FAIL, UNDECIDED
  reasons TEXT,                  -- JSON array of strings
  decision_key TEXT              -- unique per decision: a rig's random key, a batch's session key
);
CREATE TABLE IF NOT EXISTS quantities (
  decision BIGINT NOT NULL REFERENCES decisions(id),
  position INTEGER NOT NULL,     -- its place among the decision's quantities
  name TEXT NOT NULL, unit TEXT, value DOUBLE PRECISION, sd DOUBLE PRECISION, nominal DOUBLE PRECISION,
  lower DOUBLE PRECISION, upper DOUBLE PRECISION, status TEXT, meaning TEXT
);
CREATE INDEX IF NOT EXISTS decisions_by_serial ON decisions(serial, time);
CREATE INDEX IF NOT EXISTS quantities_by_decision ON quantities(decision);
)",
                     id);
}
constexpr const char* kKeyIndex = "CREATE UNIQUE INDEX IF NOT EXISTS decisions_by_key ON decisions(decision_key)";

//! A random key for a decision that brings none: 128 bits, so rigs writing at once never collide.
std::string RandomKey() {
  std::random_device device;
  return fmt::format("qc:{:08x}{:08x}{:08x}{:08x}", device(), device(), device(), device());
}

double Real(const SqlCell& c) { return c ? std::strtod(c->c_str(), nullptr) : NAN; }
std::string Text(const SqlCell& c) { return c.value_or(""); }
long Integer(const SqlCell& c) { return c ? std::stol(*c) : 0; }

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

bool IsPostgresUrl(const std::string& location) {
  return location.rfind("postgresql://", 0) == 0 || location.rfind("postgres://", 0) == 0;
}

std::string RedactedLocation(const std::string& location) {
  if (!IsPostgresUrl(location)) return location;
  std::string out = location;
  const std::size_t scheme = out.find("://") + 3;
  const std::size_t at = out.find('@', scheme), slash = out.find('/', scheme);
  if (at != std::string::npos && (slash == std::string::npos || at < slash)) {
    const std::size_t colon = out.find(':', scheme);
    if (colon != std::string::npos && colon < at) out.erase(colon, at - colon);
  }
  // ?password=...&...: the parameter and its value go
  for (std::size_t p; (p = out.find("password=")) != std::string::npos;) {
    const std::size_t end = out.find('&', p);
    out.erase(p, end == std::string::npos ? std::string::npos : end + 1 - p);
  }
  while (!out.empty() && (out.back() == '?' || out.back() == '&')) out.pop_back();
  return out;
}

History::History(const std::string& location) {
  if (IsPostgresUrl(location)) {
    if (RedactedLocation(location) != location)
      throw HistoryError(fmt::format("{}: the URL holds a password, which would show in the process list and the "
                                     "shell's history; give it in PGPASSWORD, ~/.pgpass or a service file (docs/qc.md)",
                                     RedactedLocation(location)));
    store_ = OpenPostgres(location);
  } else {
    store_ = OpenSqlite(location);
  }
  try {
    Migrate();
  } catch (const SqlError& e) {
    throw HistoryError(fmt::format("{}: {} (is it a strut QC history?)", where(), e.message));
  }
}

History::~History() = default;

const std::string& History::where() const { return store_->where(); }

void History::Migrate() {
  store_->BeginExclusive();
  try {
    store_->Exec("CREATE TABLE IF NOT EXISTS strut_schema (version INTEGER NOT NULL)");
    const SqlRows v = store_->Query("SELECT MAX(version) FROM strut_schema");
    version_ = !v.empty() && v[0][0] ? std::stoi(*v[0][0]) : (store_->TableExists("decisions") ? 1 : 0);
    if (version_ > kHistorySchemaVersion)
      throw HistoryError(fmt::format("{}: the QC history has schema version {}, newer than this strut's {}; use a "
                                     "newer strut",
                                     where(), version_, kHistorySchemaVersion));
    if (version_ < kHistorySchemaVersion) {
      if (version_ == 0) store_->Exec(Tables(store_->IdColumn()));
      if (version_ == 1) {  // the first schema: every old decision gets a key of its own
        store_->Exec("ALTER TABLE decisions ADD COLUMN decision_key TEXT");
        store_->Exec("UPDATE decisions SET decision_key = 'legacy:' || id");
        store_->Exec("ALTER TABLE quantities ADD COLUMN position INTEGER");
        store_->Exec("UPDATE quantities SET position = rowid");  // SQLite's, the order they were stored in
      }
      store_->Exec(kKeyIndex);
      store_->Query("DELETE FROM strut_schema");
      store_->Query("INSERT INTO strut_schema (version) VALUES ($1)", {static_cast<long>(kHistorySchemaVersion)});
      version_ = kHistorySchemaVersion;
    }
    store_->Exec("COMMIT");
  } catch (...) {  // whatever failed, the schema change is undone and the error goes on
    try {
      store_->Exec("ROLLBACK");
    } catch (const SqlError&) {  // a lost connection has nothing to roll back
    }
    throw;
  }
}

Recorded History::Record(const Decision& d, const std::string& time, const std::string& key) {
  if (!time.empty() && !IsUtcTime(time))
    throw std::invalid_argument("the decision's time '" + time + "' is not a UTC time YYYY-MM-DDTHH:MM:SSZ");
  const std::string at = time.empty() ? daq::UtcNowIso8601() : time;
  const std::string decision_key = key.empty() ? RandomKey() : key;
  for (int attempt = 1;; ++attempt) {
    try {
      store_->Begin();
      try {
        const SqlRows id = store_->Query(
            "INSERT INTO decisions (serial, time, session, reference, model, verdict, reasons, decision_key) "
            "VALUES ($1,$2,$3,$4,$5,$6,$7,$8) ON CONFLICT (decision_key) DO NOTHING RETURNING id",
            {d.serial, at, d.session, d.reference, d.model, std::string(ToString(d.verdict)),
             nlohmann::json(d.reasons).dump(), decision_key});
        if (id.empty()) {  // the key is there already: that decision stays, nothing is added
          const SqlRows old = store_->Query("SELECT id FROM decisions WHERE decision_key = $1", {decision_key});
          store_->Exec("COMMIT");
          return {old.empty() ? 0 : Integer(old[0][0]), false};
        }
        const long decision = Integer(id[0][0]);
        long position = 0;
        for (const QuantityDecision& q : d.quantities)
          store_->Query("INSERT INTO quantities (decision, position, name, unit, value, sd, nominal, lower, upper, "
                        "status, meaning) VALUES ($1,$2,$3,$4,$5,$6,$7,$8,$9,$10,$11)",
                        {decision, position++, q.quantity.name, q.quantity.unit, q.quantity.value, q.quantity.sd, q.nominal,
                         q.lower, q.upper, std::string(ToString(q.status)), q.meaning});
        store_->Exec("COMMIT");
        return {decision, true};
      } catch (...) {  // whatever failed, the transaction is undone and the error goes on
        try {
          store_->Exec("ROLLBACK");
        } catch (const SqlError&) {  // a lost connection has nothing to roll back
        }
        throw;
      }
    } catch (const SqlError& e) {
      if (e.failure == SqlFailure::kRetry && attempt < 8) {
        std::this_thread::sleep_for(std::chrono::milliseconds(20 * attempt));
        continue;
      }
      throw HistoryError(fmt::format("{}: the decision for serial {} was not recorded: {}", where(), d.serial,
                                     e.message));
    }
  }
}

std::vector<HistoryEntry> History::Query(const std::optional<std::string>& serial,
                                         const std::optional<std::string>& since) const {
  if (since && !std::regex_match(*since, std::regex(R"(\d{4}-\d{2}-\d{2}(T\d{2}:\d{2}(:\d{2})?Z?)?)")))
    throw std::invalid_argument("--since '" + *since + "': give a date YYYY-MM-DD or a UTC time YYYY-MM-DDTHH:MM:SSZ");
  std::string where_clause = " WHERE 1 = 1";
  std::vector<SqlValue> params;
  if (serial) {
    params.push_back(*serial);
    where_clause += fmt::format(" AND serial = ${}", params.size());
  }
  if (since) {
    params.push_back(*since);
    where_clause += fmt::format(" AND time >= ${}", params.size());
  }
  std::vector<HistoryEntry> out;
  std::map<long, std::size_t> at;
  try {
    for (const auto& row : store_->Query("SELECT id, serial, time, session, reference, model, verdict, reasons, "
                                         "decision_key FROM decisions" + where_clause + " ORDER BY time, id",
                                         params)) {
      HistoryEntry e;
      e.id = Integer(row[0]);
      e.serial = Text(row[1]);
      e.time = Text(row[2]);
      e.session = Text(row[3]);
      e.reference = Text(row[4]);
      e.model = Text(row[5]);
      e.verdict = Text(row[6]);
      e.key = Text(row[8]);
      try {
        e.reasons = nlohmann::json::parse(Text(row[7])).get<std::vector<std::string>>();
      } catch (const nlohmann::json::exception&) {  // a row written by hand: its text is the one reason
        e.reasons = {Text(row[7])};
      }
      at[e.id] = out.size();
      out.push_back(std::move(e));
    }
    // The quantities in the order they were stored (their decision's, then as Record wrote them).
    for (const auto& row : store_->Query("SELECT q.decision, q.name, q.unit, q.value, q.sd, q.nominal, q.lower, "
                                         "q.upper, q.status, q.meaning FROM quantities q JOIN decisions ON "
                                         "decisions.id = q.decision" + where_clause + " ORDER BY q.decision, q.position",
                                         params)) {
      const auto it = at.find(Integer(row[0]));
      if (it == at.end()) continue;
      QuantityDecision d;
      d.quantity.name = Text(row[1]);
      d.quantity.unit = Text(row[2]);
      d.quantity.value = Real(row[3]);
      d.quantity.sd = Real(row[4]);
      d.nominal = Real(row[5]);
      d.lower = Real(row[6]);
      d.upper = Real(row[7]);
      d.status = ParseStatus(Text(row[8]));
      d.meaning = Text(row[9]);
      out[it->second].quantities.push_back(std::move(d));
    }
  } catch (const SqlError& e) {
    throw HistoryError(fmt::format("{}: {}", where(), e.message));
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
