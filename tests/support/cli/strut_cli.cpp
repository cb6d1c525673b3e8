#include "strut_cli.h"

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <stdexcept>

namespace strut::test {

CommandResult RunStrut(const std::string& args) {
  CommandResult result;
  const std::string command = std::string(kStrutBinary) + " " + args + " 2>&1";
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) throw std::runtime_error("popen failed: " + command);
  std::array<char, 4096> buffer{};
  while (std::fgets(buffer.data(), buffer.size(), pipe) != nullptr) result.output += buffer.data();
  const int status = pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

}  // namespace strut::test
