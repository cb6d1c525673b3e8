// Running the built strut binary, for the CLI tests (tests/test_*_cli.cpp) alone: its include
// directory is only on their path, so a unit test that reaches for the CLI does not compile.
#pragma once

#include <string>

#include "test_support.h"

namespace strut::test {

//! The strut binary these tests run (built before them).
inline constexpr const char* kStrutBinary = STRUT_BINARY;

struct CommandResult {
  int exit_code = -1;
  std::string output;  //!< stdout and stderr together
};

//! Runs the built strut binary with the given argument string (shell-quoted by the caller).
CommandResult RunStrut(const std::string& args);

}  // namespace strut::test
