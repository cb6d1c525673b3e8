#pragma once
// Crash-safe file replacement, the one way strut writes an output file: a reader (or a crash at
// any moment) sees either the old file or the complete new one, never a part.

#include <stdexcept>
#include <string>
#include <string_view>

namespace strut::daq {

//! A file that could not be written; the message names the target, the failed step and why
//! ("out/s.h5: cannot write: renaming out/s.h5.partial onto it: Permission denied").
class FileWriteError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

//! Replaces `path` with `bytes`: writes and fsyncs `path`.partial, renames it over `path`, then
//! fsyncs the folder so that the rename itself survives a crash. On failure the partial file is
//! removed and `path` keeps what it held; throws FileWriteError. A failed fsync of the folder,
//! after the rename, only warns: the file is complete then and must not be reported unwritten.
void WriteFileAtomically(const std::string& path, std::string_view bytes);

//! Makes a new directory entry (a created or renamed file at `path`) durable by fsyncing its
//! folder; warns, naming the folder, when that fails.
void SyncDirectoryOf(const std::string& path);

}  // namespace strut::daq
