// Running the built strut binary, for the CLI tests (tests/test_*_cli.cpp) alone: its include
// directory is only on their path, so a unit test that reaches for the CLI does not compile.
#pragma once

#include <sys/types.h>

#include <string>
#include <vector>

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

//! Starts `argv` (argv[0] a path, not looked up on PATH) as a child process with this process's
//! environment: its pid, or -1 when it could not be started. The caller waits for it.
pid_t Spawn(const std::vector<std::string>& argv);

}  // namespace strut::test
