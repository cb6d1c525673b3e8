// Helpers every test may use: temporary directories, files, shell commands, Chromium, loopback ports.
// They stand on no strut library, so that linking them adds no layer to a test (tests/CMakeLists.txt).
#pragma once

#include <string>
#include <utility>
#include <vector>

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

//! Debian's Chromium, which renders reports in the tests (scripts/install-deps.sh installs it).
inline constexpr const char* kChromium = "/usr/bin/chromium";
bool ChromiumAvailable();

//! The message of the `Error` that `call` throws, "" when it throws none; any other exception
//! propagates and fails the test.
template <class Error, class F>
std::string ErrorOf(F&& call) {
  try {
    call();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

//! A shell command's exit code, stdout and stderr (captured in files named after `stem`).
struct ShellResult {
  int exit_code = -1;
  std::string out;
  std::string err;
};
ShellResult Shell(const std::string& command, const std::string& stem);

//! Headless Chromium with a fresh profile in `profile_dir`, no network, scripts given 5 s.
std::string ChromiumCommand(const std::string& profile_dir);

//! The whole file as a string ("" when it cannot be read).
std::string ReadFile(const std::string& path);

//! Occurrences of `needle` in `haystack`.
std::size_t Count(const std::string& haystack, const std::string& needle);

//! A loopback port nobody listens on at the moment (the kernel's pick, released): SOCK_STREAM for a
//! Modbus TCP server, SOCK_DGRAM for a CAN-over-UDP receiver.
int FreeLoopbackPort(int type);

//! A TCP connection to 127.0.0.1:port, its descriptor (the caller closes it); -1 when refused.
int ConnectToLoopback(int port);

//! Whether a TCP connection to the loopback port is accepted now (a server is listening there).
bool AcceptsOnLoopback(int port);

//! Lowers the file size limit while alive, so that writes fail half-way (EFBIG, not a signal).
class FileSizeLimit {
 public:
  explicit FileSizeLimit(unsigned long bytes);
  ~FileSizeLimit();
  FileSizeLimit(const FileSizeLimit&) = delete;
  FileSizeLimit& operator=(const FileSizeLimit&) = delete;

 private:
  unsigned long previous_soft_ = 0;
  void (*previous_handler_)(int) = nullptr;
};

}  // namespace strut::test
