// The QC history's two databases behind one SQL (docs/qc.md): SQLite, embedded, and PostgreSQL, a
// server every rig of a line shares. The history speaks the SQL both accept ($1 parameters,
// INSERT ... ON CONFLICT DO NOTHING RETURNING); a store runs it on its connection.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <variant>
#include <vector>

namespace strut::qc {

//! A parameter: NULL, text, a real (NaN goes in as NULL) or an integer.
using SqlValue = std::variant<std::monostate, std::string, double, long>;
//! A cell of a result: NULL, or its text (a real as its shortest exact decimal).
using SqlCell = std::optional<std::string>;
using SqlRows = std::vector<std::vector<SqlCell>>;

//! Why a statement failed, as the history tells a rig.
enum class SqlFailure {
  kRetry,  //!< a transaction lost to another writer (serialization, deadlock, busy): run it again
  kOther,  //!< anything else: the message says what
};

//! A failed statement (HistoryError is made from it, naming the database).
struct SqlError {
  SqlFailure failure;
  std::string message;
};

class HistoryStore {
 public:
  virtual ~HistoryStore() = default;
  //! Statements without results; throws SqlError.
  virtual void Exec(const std::string& sql) = 0;
  //! A statement with parameters $1, $2, ... and its rows; throws SqlError.
  virtual SqlRows Query(const std::string& sql, const std::vector<SqlValue>& params = {}) = 0;
  //! Begins a write transaction.
  virtual void Begin() = 0;
  //! Begins a transaction that holds the database's write lock for schema changes.
  virtual void BeginExclusive() = 0;
  virtual bool TableExists(const std::string& name) = 0;
  //! The id column of `decisions` in this database's words.
  virtual std::string IdColumn() const = 0;
  //! The database in messages and logs: an SQLite file, or a URL without a password.
  virtual const std::string& where() const = 0;
};

std::unique_ptr<HistoryStore> OpenSqlite(const std::string& path);
//! Throws HistoryError naming the (redacted) URL when libpq cannot connect, or when this strut was
//! built without libpq.
std::unique_ptr<HistoryStore> OpenPostgres(const std::string& url);

}  // namespace strut::qc
