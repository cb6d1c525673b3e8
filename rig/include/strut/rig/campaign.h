// What a matrix run on the rig settles before anything connects or moves (docs/rig-run.md): how
// it starts at its session file (a new session, or the resume of an interrupted run from its
// journal), the sample rate it records at, the experiments it runs, and the matrix checked
// against the limits; then the recorder it records with.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "strut/daq/recorder.h"
#include "strut/daq/session.h"
#include "strut/rig/matrix_runner.h"
#include "strut/rig/safety.h"
#include "strut/rig/test_matrix.h"
#include "strut/rig/top_out.h"

namespace strut::rig {

//! Where a run records and how it starts.
struct RunStart {
  std::string output;   //!< the session file
  bool resume = false;  //!< go on with the interrupted run in its journal (daq::JournalPath(output))
  bool force = false;   //!< replace a session or a journal at the output
  //! The damper's serial number: needed for a new session; a resume checks it against the
  //! session's when given.
  std::string serial;
};

//! What is at a run's output before it starts.
struct OutputState {
  std::string journal;  //!< the journal's path (daq::JournalPath of the session file)
  bool session_exists = false;
  bool journal_exists = false;
  //! As the file system has it.
  static OutputState Of(const std::string& output);
};

//! Refuses a start that the output does not allow, naming the files (std::invalid_argument): a
//! resume that is also forced, or that has no journal to go on from; a new session over the
//! journal of an interrupted run unless forced, or without a serial number. Whether a new
//! session may replace an existing file is the caller's output check.
void CheckStart(const RunStart& start, const OutputState& output);

//! Sample sets per second a run records at: `requested` (the acquisition's rate as given), else
//! the matrix file's sample_rate, else 200 Hz. Throws std::invalid_argument naming the matrix
//! when the requested rate is not the matrix file's.
double RunSampleRate(std::optional<double> requested, const MatrixPlan& plan);

//! The experiments a run records: every one of `matrix` for a new session; for a resume what
//! `so_far` (the session as its journal holds it) lacks, as RemainingExperiments gives them.
//! Throws std::invalid_argument when a resume's serial number is not the session's.
std::vector<RunItem> ExperimentsToRun(const RunStart& start, const std::vector<MatrixEntry>& matrix,
                                      const daq::Session* so_far);

//! CheckMatrix of `items`, and CheckTopOut of the reference the run starts with (if any), every
//! violation in one std::invalid_argument naming the matrix and the limits (`matrix_name`,
//! `limits_name`: a file, "standard", "defaults") before the rig moves.
void RefuseUnsafeMatrix(const std::vector<RunItem>& items, const SafetyConfig& safety, double sample_rate,
                        const ResponsePredictor& predictor, const std::string& matrix_name,
                        const std::string& limits_name, const std::optional<TopOutOptions>& top_out = std::nullopt);

//! The top-out reference a run starts with: `options` for a new session when `requested`; none
//! for a resume, whose session holds the first run's reference already (its zero, or the event
//! that says why there is none): a resume neither repeats nor loses it.
std::optional<TopOutOptions> TopOutToRun(const RunStart& start, bool requested, const TopOutOptions& options);

//! What a new session of a run records: the damper, the rig, the operator, the matrix (its
//! file's text or "standard") and the limits in force.
daq::RecordingMetadata RunMetadata(const std::string& serial, const std::string& rig, const std::string& operator_name,
                                   const std::string& matrix, const SafetyConfig& safety);

//! The channel limits a session recorded (/recording/limits, as RunMetadata wrote them): each of
//! stroke, force and pressure enabled with its recorded lower and upper limit where the session
//! has both, disabled where it has not (a session of another tool has none). For a replay's
//! monitor, which draws them and shows the margins to them; the actions are not recorded.
SafetyConfig RecordedLimits(const daq::Session& session);

//! The recorder of a run: a new session with `metadata` (replacing one there when forced), or
//! the resumed session at `start.output`, with an event saying so and `to_run` experiments to go.
daq::Recorder OpenRunRecorder(const RunStart& start, const daq::RecordingMetadata& metadata, std::size_t to_run);

//! Closes the resumed session at `output` that has nothing left to run: the run was cut off
//! after its last record ended.
void CloseCompletedResume(const std::string& output);

}  // namespace strut::rig
