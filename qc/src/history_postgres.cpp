// The QC history on a PostgreSQL server (Debian's libpq), shared by every rig of a line. The
// password comes from where libpq looks (PGPASSWORD, ~/.pgpass, a service file), never from the URL.
#include <fmt/format.h>
#include <libpq-fe.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <cstring>

#include "history_store.h"
#include "strut/qc/history.h"

namespace strut::qc {
namespace {

class PostgresStore : public HistoryStore {
 public:
  explicit PostgresStore(const std::string& url) : where_(RedactedLocation(url)) {
    conn_ = PQconnectdb(url.c_str());
    if (!conn_ || PQstatus(conn_) != CONNECTION_OK) {
      const std::string why = conn_ ? Trimmed(PQerrorMessage(conn_)) : "out of memory";
      PQfinish(conn_);
      throw HistoryError(fmt::format("{}: cannot connect to the QC history: {}", where_, why));
    }
    // "relation already exists, skipping" and the like: the history's own business.
    PQsetNoticeProcessor(conn_, [](void*, const char* message) { spdlog::debug("postgresql: {}", Trimmed(message)); },
                         nullptr);
  }
  ~PostgresStore() override { PQfinish(conn_); }

  void Exec(const std::string& sql) override { Check(PQexec(conn_, sql.c_str())); }

  SqlRows Query(const std::string& sql, const std::vector<SqlValue>& params) override {
    std::vector<std::string> text(params.size());
    std::vector<const char*> values(params.size(), nullptr);
    for (std::size_t i = 0; i < params.size(); ++i) {
      if (const auto* t = std::get_if<std::string>(&params[i]))
        text[i] = *t;
      else if (const auto* d = std::get_if<double>(&params[i])) {
        if (!std::isfinite(*d)) continue;
        text[i] = fmt::format("{}", *d);  // the shortest decimal that reads back as the same double
      } else if (const auto* l = std::get_if<long>(&params[i]))
        text[i] = std::to_string(*l);
      else
        continue;
      values[i] = text[i].c_str();
    }
    PGresult* r = PQexecParams(conn_, sql.c_str(), static_cast<int>(params.size()), nullptr, values.data(), nullptr,
                               nullptr, 0);
    Check(r, true);
    SqlRows rows;
    for (int i = 0; i < PQntuples(r); ++i) {
      std::vector<SqlCell> row;
      for (int c = 0; c < PQnfields(r); ++c)
        row.emplace_back(PQgetisnull(r, i, c) ? SqlCell() : SqlCell(PQgetvalue(r, i, c)));
      rows.push_back(std::move(row));
    }
    PQclear(r);
    return rows;
  }

  void Begin() override { Exec("BEGIN"); }
  void BeginExclusive() override {
    Exec("BEGIN");
    Exec("SELECT pg_advisory_xact_lock(727374)");  // one schema change at a time over every rig
  }
  bool TableExists(const std::string& name) override {
    return !Query("SELECT 1 FROM information_schema.tables WHERE table_schema = current_schema() AND table_name = $1",
                  {name})
                .empty();
  }
  std::string IdColumn() const override { return "id BIGSERIAL PRIMARY KEY"; }
  const std::string& where() const override { return where_; }

 private:
  static std::string Trimmed(std::string s) {
    while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
    return s;
  }
  //! Throws SqlError for a failed result (and frees it); `keep` leaves a good one to the caller.
  void Check(PGresult* r, bool keep = false) {
    const ExecStatusType status = r ? PQresultStatus(r) : PGRES_FATAL_ERROR;
    if (status == PGRES_COMMAND_OK || status == PGRES_TUPLES_OK) {
      if (!keep) PQclear(r);
      return;
    }
    const char* state = r ? PQresultErrorField(r, PG_DIAG_SQLSTATE) : nullptr;
    const bool retry = state && (std::strcmp(state, "40001") == 0 || std::strcmp(state, "40P01") == 0);
    std::string why = Trimmed(r ? PQresultErrorMessage(r) : PQerrorMessage(conn_));
    if (PQstatus(conn_) == CONNECTION_BAD)
      why = fmt::format("the connection to the server was lost ({})", why.empty() ? "no reply" : why);
    PQclear(r);
    throw SqlError{retry ? SqlFailure::kRetry : SqlFailure::kOther, why};
  }
  std::string where_;
  PGconn* conn_ = nullptr;
};

}  // namespace

std::unique_ptr<HistoryStore> OpenPostgres(const std::string& url) { return std::make_unique<PostgresStore>(url); }

}  // namespace strut::qc
