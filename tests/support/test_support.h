// Helpers shared by the tests: temporary directories and running the strut binary.
#pragma once

#include <string>

namespace strut::test {

//! A fresh directory under the system temp dir, removed when the object dies.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::string& path() const { return path_; }
  std::string file(const std::string& name) const { return path_ + "/" + name; }

 private:
  std::string path_;
};

struct CommandResult {
  int exit_code = -1;
  std::string output;  //!< stdout and stderr together
};

//! Runs the built strut binary with the given argument string (shell-quoted by the caller).
CommandResult RunStrut(const std::string& args);

}  // namespace strut::test
