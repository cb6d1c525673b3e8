// The QC history in an embedded SQLite file (Debian's libsqlite3).
#include <fmt/format.h>
#include <sqlite3.h>

#include <cmath>

#include "history_store.h"
#include "strut/qc/history.h"

namespace strut::qc {
namespace {

class SqliteStore : public HistoryStore {
 public:
  explicit SqliteStore(const std::string& path) : path_(path) {
    if (sqlite3_open_v2(path.c_str(), &db_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, nullptr) != SQLITE_OK) {
      const std::string why = db_ ? sqlite3_errmsg(db_) : "out of memory";
      sqlite3_close(db_);
      throw HistoryError(fmt::format("{}: cannot open the QC history: {}", path, why));
    }
    sqlite3_busy_timeout(db_, 5000);  // another station writing: wait up to 5 s, then retry or fail
  }
  ~SqliteStore() override { sqlite3_close(db_); }

  void Exec(const std::string& sql) override {
    char* error = nullptr;
    const int rc = sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &error);
    if (rc == SQLITE_OK) return;
    const std::string why = error ? error : sqlite3_errstr(rc);
    sqlite3_free(error);
    throw SqlError{IsBusy(rc) ? SqlFailure::kRetry : SqlFailure::kOther, why};
  }

  SqlRows Query(const std::string& sql, const std::vector<SqlValue>& params) override {
    sqlite3_stmt* stmt = nullptr;
    if (sqlite3_prepare_v2(db_, sql.c_str(), -1, &stmt, nullptr) != SQLITE_OK) Fail(sqlite3_errcode(db_));
    const std::unique_ptr<sqlite3_stmt, int (*)(sqlite3_stmt*)> owner(stmt, sqlite3_finalize);
    for (std::size_t i = 0; i < params.size(); ++i) {
      const int at = static_cast<int>(i) + 1;
      int rc = SQLITE_OK;
      if (const auto* t = std::get_if<std::string>(&params[i]))
        rc = sqlite3_bind_text(stmt, at, t->c_str(), -1, SQLITE_TRANSIENT);
      else if (const auto* d = std::get_if<double>(&params[i]))
        rc = std::isfinite(*d) ? sqlite3_bind_double(stmt, at, *d) : sqlite3_bind_null(stmt, at);
      else if (const auto* l = std::get_if<long>(&params[i]))
        rc = sqlite3_bind_int64(stmt, at, *l);
      else
        rc = sqlite3_bind_null(stmt, at);
      if (rc != SQLITE_OK) Fail(rc);
    }
    SqlRows rows;
    for (int rc; (rc = sqlite3_step(stmt)) != SQLITE_DONE;) {
      if (rc != SQLITE_ROW) Fail(rc);
      std::vector<SqlCell> row;
      for (int c = 0; c < sqlite3_column_count(stmt); ++c) {
        switch (sqlite3_column_type(stmt, c)) {
          case SQLITE_NULL: row.emplace_back(std::nullopt); break;
          case SQLITE_FLOAT: row.emplace_back(fmt::format("{}", sqlite3_column_double(stmt, c))); break;
          case SQLITE_INTEGER: row.emplace_back(std::to_string(sqlite3_column_int64(stmt, c))); break;
          default: row.emplace_back(reinterpret_cast<const char*>(sqlite3_column_text(stmt, c)));
        }
      }
      rows.push_back(std::move(row));
    }
    return rows;
  }

  void Begin() override { Exec("BEGIN IMMEDIATE"); }  // the write lock now: no deadlock on upgrading it later
  void BeginExclusive() override { Exec("BEGIN IMMEDIATE"); }
  bool TableExists(const std::string& name) override {
    return !Query("SELECT name FROM sqlite_master WHERE type = 'table' AND name = $1", {name}).empty();
  }
  std::string IdColumn() const override { return "id INTEGER PRIMARY KEY"; }
  const std::string& where() const override { return path_; }

 private:
  static bool IsBusy(int rc) { return (rc & 0xff) == SQLITE_BUSY || (rc & 0xff) == SQLITE_LOCKED; }
  [[noreturn]] void Fail(int rc) { throw SqlError{IsBusy(rc) ? SqlFailure::kRetry : SqlFailure::kOther, sqlite3_errmsg(db_)}; }
  std::string path_;
  sqlite3* db_ = nullptr;
};

}  // namespace

std::unique_ptr<HistoryStore> OpenSqlite(const std::string& path) { return std::make_unique<SqliteStore>(path); }

}  // namespace strut::qc
