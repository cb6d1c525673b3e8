#include "strut/daq/atomic_file.h"

#include <fcntl.h>
#include <spdlog/fmt/fmt.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>

namespace strut::daq {
namespace {

// The temporary file of a write: removed unless it was renamed onto the target.
class PartialFile {
 public:
  explicit PartialFile(const std::string& target) : target_(target), path_(target + ".partial") {}
  ~PartialFile() {
    if (fd_ >= 0) ::close(fd_);
    if (committed_) return;
    std::error_code ignored;
    std::filesystem::remove(path_, ignored);
  }
  PartialFile(const PartialFile&) = delete;
  PartialFile& operator=(const PartialFile&) = delete;

  //! Writes `bytes` and makes them durable: without fsync a crash after the rename could leave
  //! the target name on an empty file.
  void Write(std::string_view bytes) {
    fd_ = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
    if (fd_ < 0) Fail("creating " + path_, errno);
    std::size_t done = 0;
    while (done < bytes.size()) {
      const ssize_t n = ::write(fd_, bytes.data() + done, bytes.size() - done);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) Fail("writing " + path_, n < 0 ? errno : EIO);
      done += static_cast<std::size_t>(n);
    }
    if (::fsync(fd_) != 0) Fail("syncing " + path_, errno);
    const int fd = fd_;
    fd_ = -1;
    if (::close(fd) != 0) Fail("closing " + path_, errno);
  }

  //! Atomically replaces the target with the written file.
  void Commit() {
    if (std::rename(path_.c_str(), target_.c_str()) != 0) Fail("renaming " + path_ + " onto it", errno);
    committed_ = true;
  }

 private:
  [[noreturn]] void Fail(const std::string& step, int error) const {
    throw FileWriteError(fmt::format("{}: cannot write: {}: {}", target_, step, std::strerror(error)));
  }

  std::string target_;
  std::string path_;
  int fd_ = -1;
  bool committed_ = false;
};

}  // namespace

void WriteFileAtomically(const std::string& path, std::string_view bytes) {
  PartialFile partial(path);
  partial.Write(bytes);
  partial.Commit();
  SyncDirectoryOf(path);
}

void SyncDirectoryOf(const std::string& path) {
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  const std::string directory = parent.empty() ? std::string(".") : parent.string();
  const int dir = ::open(directory.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dir < 0 || ::fsync(dir) != 0) {
    spdlog::warn("{}: syncing directory {} failed: {}", path, directory, std::strerror(errno));
  }
  if (dir >= 0) ::close(dir);
}

}  // namespace strut::daq
