// A strut built without libpq: a postgresql:// history is refused with what to install.
#include <fmt/format.h>

#include "history_store.h"
#include "strut/qc/history.h"

namespace strut::qc {

std::unique_ptr<HistoryStore> OpenPostgres(const std::string& url) {
  throw HistoryError(fmt::format("{}: this strut was built without PostgreSQL; install libpq-dev and build again "
                                 "(scripts/install-deps.sh)",
                                 RedactedLocation(url)));
}

}  // namespace strut::qc
