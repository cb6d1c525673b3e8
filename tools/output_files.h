// Outputs that never destroy data: every command that writes checks its output paths before the
// work starts (not an input, not an existing session unless --force, the folder writable) and
// writes atomically (a temporary file beside the target, then a rename).
#pragma once

#include <exception>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <vector>

namespace strut::tools {

//! Exit codes beyond 0 (success) and 1 (an error: bad input, bad options, I/O).
inline constexpr int kExitNotConverged = 2;     //!< a fit did not converge
inline constexpr int kExitAboveNoiseFloor = 3;  //!< a fit converged, but the model does not explain the data
inline constexpr int kExitRunPaused = 4;   //!< `rig run`: paused (operator or a hold trip); resumable
inline constexpr int kExitRunAborted = 5;  //!< `rig run`: stopped by a trip or a lost device; resumable
inline constexpr int kExitDifferent = 6;   //!< `bench units --compare`: the runs differ beyond the tolerance
inline constexpr int kExitIncomplete = 7;  //!< `batch`: shards failed or are missing; running it again resumes

//! Thrown by a command to end with a given exit code after it has printed its results.
class ExitCode : public std::exception {
 public:
  explicit ExitCode(int code) : code_(code) {}
  int code() const { return code_; }
  const char* what() const noexcept override { return "exit code"; }

 private:
  int code_;
};

//! Throws std::invalid_argument naming `option` and `path` when writing `path` could lose data or
//! cannot work: it is one of `inputs` (the same file by any name), it is an existing HDF5 session
//! and `force` is false, it is a directory, or its folder does not exist or is not writable.
void CheckOutputPath(const std::string& option, const std::string& path, const std::vector<std::string>& inputs,
                     bool force = false);

//! Writes `text` to `path` atomically (daq::WriteFileAtomically) and logs it.
void WriteTextOutput(const std::string& path, const std::string& text);
//! Writes `json` as every command's JSON output is laid out (one space of indent, a final newline).
void WriteJsonOutput(const std::string& path, const nlohmann::json& json);

}  // namespace strut::tools
