// daq::WriteFileAtomically, the one crash-safe write behind sessions, reports and text outputs:
// the target holds either its old bytes or exactly the new ones, and no partial file is left.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include "strut/daq/atomic_file.h"
#include "test_support.h"

namespace strut::daq {
namespace {

using test::FileSizeLimit;
using test::ReadFile;
using test::TempDir;
namespace fs = std::filesystem;

// Every byte value, NULs included, in a length that takes more than one write() on most systems.
std::string BinaryBytes(std::size_t size) {
  std::mt19937 rng(7);
  std::string bytes(size, '\0');
  for (char& c : bytes) c = static_cast<char>(rng() & 0xff);
  return bytes;
}

// `path` holds exactly `bytes`, and no partial file is left beside it.
void ExpectHolds(const std::string& path, const std::string& bytes) {
  EXPECT_EQ(ReadFile(path), bytes);
  EXPECT_FALSE(fs::exists(path + ".partial"));
}

TEST(AtomicFile, WritesTheBytesExactlyAndLeavesNoPartialFile) {
  TempDir dir;
  const std::string path = dir.file("out.bin");
  const std::string bytes = BinaryBytes(3 * 1024 * 1024 + 17);
  WriteFileAtomically(path, bytes);
  ExpectHolds(path, bytes);
  WriteFileAtomically(dir.file("empty.txt"), "");
  EXPECT_EQ(fs::file_size(dir.file("empty.txt")), 0u);
  EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator()), 2);
}

TEST(AtomicFile, ReplacesAnExistingFileLongerOrShorter) {
  TempDir dir;
  const std::string path = dir.file("report.html");
  std::ofstream(path) << std::string(1000, 'x');
  WriteFileAtomically(path, "short");
  EXPECT_EQ(ReadFile(path), "short");
  WriteFileAtomically(path, std::string(5000, 'y'));
  ExpectHolds(path, std::string(5000, 'y'));
}

// The message of the FileWriteError a write throws ("" when none).
constexpr auto ErrorOf = [](auto&& call) { return test::ErrorOf<FileWriteError>(call); };

TEST(AtomicFile, IntoAMissingFolderNamesThePathAndTheStepAndCreatesNothing) {
  TempDir dir;
  const std::string path = dir.file("missing/out.txt");
  const std::string message = ErrorOf([&] { WriteFileAtomically(path, "text"); });
  EXPECT_EQ(message, path + ": cannot write: creating " + path + ".partial: No such file or directory");
  EXPECT_TRUE(fs::is_empty(dir.path()));
}

// The message of writing "new" to `path` as a user without write permission there: this process
// when it is not root, else a child that drops to nobody (root writes into read-only folders).
std::string ErrorWritingUnprivileged(const std::string& path) {
  if (geteuid() != 0) return ErrorOf([&] { WriteFileAtomically(path, "new"); });
  int pipe_fds[2];
  if (pipe(pipe_fds) != 0) return "(no pipe)";
  const pid_t child = fork();
  if (child == 0) {
    close(pipe_fds[0]);
    std::string message = "(cannot drop privileges)";
    if (setgid(65534) == 0 && setuid(65534) == 0) message = ErrorOf([&] { WriteFileAtomically(path, "new"); });
    const ssize_t ignored = write(pipe_fds[1], message.data(), message.size());
    (void)ignored;
    _exit(0);
  }
  close(pipe_fds[1]);
  std::string message;
  char buffer[512];
  for (ssize_t n; (n = read(pipe_fds[0], buffer, sizeof buffer)) > 0;) message.append(buffer, static_cast<std::size_t>(n));
  close(pipe_fds[0]);
  waitpid(child, nullptr, 0);
  return message;
}

TEST(AtomicFile, IntoAReadOnlyFolderKeepsTheOldFile) {
  TempDir dir;
  const std::string folder = dir.file("ro"), path = folder + "/out.txt";
  fs::create_directory(folder);
  std::ofstream(path) << "old";
  fs::permissions(dir.path(), fs::perms::owner_all | fs::perms::group_read | fs::perms::group_exec |
                                  fs::perms::others_read | fs::perms::others_exec);
  fs::permissions(folder, fs::perms::owner_read | fs::perms::owner_exec | fs::perms::group_read |
                              fs::perms::group_exec | fs::perms::others_read | fs::perms::others_exec);
  const std::string message = ErrorWritingUnprivileged(path);
  fs::permissions(folder, fs::perms::owner_all);
  EXPECT_EQ(message, path + ": cannot write: creating " + path + ".partial: Permission denied");
  ExpectHolds(path, "old");
}

TEST(AtomicFile, AWriteFailingHalfWayKeepsTheOldFileAndRemovesThePartialOne) {
  TempDir dir;
  const std::string path = dir.file("session.h5");
  std::ofstream(path) << "old contents";
  std::string message;
  {
    const FileSizeLimit limit(64 * 1024);
    message = ErrorOf([&] { WriteFileAtomically(path, BinaryBytes(256 * 1024)); });
  }
  EXPECT_EQ(message, path + ": cannot write: writing " + path + ".partial: File too large");
  ExpectHolds(path, "old contents");
}

TEST(AtomicFile, AFailedRenameLeavesTheTargetAndNoPartialFile) {
  TempDir dir;
  const std::string path = dir.file("taken");
  fs::create_directory(path);  // a folder with a file in it: rename() cannot replace it
  std::ofstream(path + "/inside") << "kept";
  const std::string message = ErrorOf([&] { WriteFileAtomically(path, "new"); });
  EXPECT_EQ(message.rfind(path + ": cannot write: renaming " + path + ".partial onto it: ", 0), 0u) << message;
  EXPECT_EQ(ReadFile(path + "/inside"), "kept");
  EXPECT_FALSE(fs::exists(path + ".partial"));
}

TEST(AtomicFile, SyncingTheFolderOfAMissingPathOnlyWarns) {
  EXPECT_NO_THROW(SyncDirectoryOf("/no/such/folder/file"));
}

}  // namespace
}  // namespace strut::daq
