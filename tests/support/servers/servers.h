// Real servers the tests start in a folder of their own (tests/support/servers/*.sh) and stop by
// their process ids. Where one cannot start (not root, not installed) a test skips saying why,
// unless STRUT_REQUIRE_SERVERS is set (CI, .ci/run): there it must run, and fails instead.
#pragma once

#include <gtest/gtest.h>

#include <cstdlib>
#include <string>

namespace strut::test {

inline constexpr const char* kServersDir = STRUT_SOURCE_DIR "/tests/support/servers";

inline bool ServersRequired() { return std::getenv("STRUT_REQUIRE_SERVERS") != nullptr; }

}  // namespace strut::test

//! In a test body: skip with `why` (loudly), or fail where servers are required.
#define STRUT_SERVER_UNAVAILABLE(why)                                                             \
  do {                                                                                            \
    if (::strut::test::ServersRequired()) FAIL() << "STRUT_REQUIRE_SERVERS is set, but " << (why); \
    GTEST_SKIP() << "NOT RUN: " << (why);                                                         \
  } while (0)
