#include "test_support.h"
#include "python_peer.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/resource.h>
#include <sys/wait.h>

#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <unistd.h>
#include <stdexcept>

namespace strut::test {

TempDir::TempDir() {
  std::string pattern = (std::filesystem::temp_directory_path() / "strut-test-XXXXXX").string();
  if (mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
  path_ = pattern;
}

TempDir::~TempDir() {
  std::error_code ec;
  std::filesystem::remove_all(path_, ec);
}

bool ChromiumAvailable() { return access(kChromium, X_OK) == 0; }

ShellResult Shell(const std::string& command, const std::string& stem) {
  const int status = std::system((command + " >" + stem + ".out 2>" + stem + ".err").c_str());
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, ReadFile(stem + ".out"), ReadFile(stem + ".err")};
}

std::string ChromiumCommand(const std::string& profile_dir) {
  // Generous: a busy CI machine (two cores, tests in parallel) slows Chromium's start many times over.
  return std::string("timeout 240 ") + kChromium +
         " --headless --no-sandbox --disable-gpu --disable-quic --no-first-run --disable-background-networking"
         " --disable-component-update --disable-sync --disable-dev-shm-usage --hide-scrollbars"
         " --user-data-dir=" +
         profile_dir + " --virtual-time-budget=5000";
}

std::string PythonWithH5py() {
  for (const char* candidate : {"python3", "/usr/bin/python3"}) {
    const std::string probe = std::string(candidate) + " -c 'import h5py, numpy' >/dev/null 2>&1";
    if (std::system(probe.c_str()) == 0) return candidate;
  }
  return {};
}

int RunPython(const std::string& python, const TempDir& dir, const std::string& script, const std::string& arguments) {
  const std::string script_path = dir.file("script.py");
  std::ofstream(script_path) << script;
  const int status = std::system((python + " " + script_path + " " + arguments).c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

std::size_t Count(const std::string& haystack, const std::string& needle) {
  std::size_t n = 0;
  for (std::size_t at = haystack.find(needle); at != std::string::npos; at = haystack.find(needle, at + needle.size()))
    ++n;
  return n;
}

int FreeLoopbackPort(int type) {
  const int s = socket(AF_INET, type | SOCK_CLOEXEC, 0);
  if (s < 0) throw std::runtime_error("FreeLoopbackPort: no socket");
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof a;
  const bool ok = bind(s, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0 &&
                  getsockname(s, reinterpret_cast<sockaddr*>(&a), &len) == 0;
  close(s);
  if (!ok) throw std::runtime_error("FreeLoopbackPort: no loopback port");
  return ntohs(a.sin_port);
}

int ConnectToLoopback(int port) {
  const int s = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (s < 0) return -1;
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  if (connect(s, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
    close(s);
    return -1;
  }
  return s;
}

bool AcceptsOnLoopback(int port) {
  const int s = ConnectToLoopback(port);
  if (s >= 0) close(s);
  return s >= 0;
}

FileSizeLimit::FileSizeLimit(unsigned long bytes) {
  rlimit limit{};
  getrlimit(RLIMIT_FSIZE, &limit);
  previous_soft_ = limit.rlim_cur;
  previous_handler_ = std::signal(SIGXFSZ, SIG_IGN);
  limit.rlim_cur = bytes;
  setrlimit(RLIMIT_FSIZE, &limit);
}

FileSizeLimit::~FileSizeLimit() {
  rlimit limit{};
  getrlimit(RLIMIT_FSIZE, &limit);
  limit.rlim_cur = previous_soft_;
  setrlimit(RLIMIT_FSIZE, &limit);
  std::signal(SIGXFSZ, previous_handler_);
}

}  // namespace strut::test
