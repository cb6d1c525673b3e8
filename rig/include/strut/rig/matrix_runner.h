// The matrix runner (docs/rig-run.md): runs a shaker test matrix on the rig through the device
// interfaces only (daq::ActuatorController, daq::AcquisitionModule) and records it with the
// streaming daq::Recorder. Per experiment: move to the static position (rate-limited by the
// controller at SetPoint::static_rate, amplitude zero), start the sine with the amplitude ramped in
// over whole cycles, wait for steady state (SteadyStateDetector; on its time limit record anyway,
// marked not steady), record the requested whole periods, ramp out at the end of a cycle, go on.
// The safety detectors (safety.h) run on every block and status read; pause and stop requests
// are honoured at experiment boundaries and at once respectively.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "strut/daq/acquisition.h"
#include "strut/daq/controller.h"
#include "strut/daq/recorder.h"
#include "strut/rig/safety.h"
#include "strut/rig/steady_state.h"
#include "strut/rig/test_matrix.h"
#include "strut/rig/top_out.h"

namespace strut::rig {

//! How each experiment is run (defaults in docs/rig-run.md).
struct RunnerOptions {
  long periods = 3;            //!< whole steady-state periods recorded per experiment
  int ramp_cycles = 2;         //!< whole cycles of amplitude ramp in and out (the controller ramps)
  double static_rate = 0.01;   //!< m/s, the controller's rate limit of moves to a static position
  SteadyStateTolerances steady;
  //! One loop of the runner: the longest wait for acquired samples. Each loop also beats the
  //! controller's heartbeat and reads its status.
  std::chrono::milliseconds loop{20};
  //! Controller calls failing for this long mean the controller is lost (the run stops).
  std::chrono::milliseconds controller_grace{1000};
  //! Extra time allowed beyond what a move or a ramp should take before it counts as stuck.
  std::chrono::milliseconds settle_margin{5000};
  //! Recordings of one experiment cut by lost samples (a sequence gap) before the run stops.
  int max_attempts = 3;
  //! Pressure channel's reference in the session ("gauge" or "absolute").
  std::string pressure_reference = "gauge";
  //! Stroke within this of the static position counts as arrived (m).
  double position_tolerance = 2e-4;
  //! A controller whose only latched fault is heartbeat-lost (its watchdog fired because an earlier
  //! run stopped beating: a crash, kill -9) is reset at the start, with an event, instead of refused.
  //! For resumed runs; any other fault is always refused.
  bool reset_heartbeat_fault = false;
  //! Recorded seconds per second of the stream's clock: a simulated rig served at --speed X
  //! streams X times its recorded sample rate. The runner records at the stream's rate / this,
  //! with the samples' times put on the recorded clock (daq::ToRecordedTime); its own waits and
  //! the safety detectors stay on the wall clock. 1 for a real rig.
  double stream_speed = 1.0;
  //! The top-out reference before the first experiment (top_out.h, docs/rig-run.md): finds the
  //! stroke zero and records it in the session's /calibration. None: no reference (a resumed run,
  //! `--no-top-out`, the tests' plants).
  std::optional<TopOutOptions> top_out;
  bool IsValid(std::string* error) const;
};

enum class RunPhase { kStarting, kReference, kMoving, kRampIn, kSettling, kRecording, kRampOut, kSafing, kDone };
std::string_view ToString(RunPhase phase);

//! What the progress display shows; sent at every phase change and at most every 100 ms.
struct Progress {
  std::string experiment;  //!< its label in the session
  std::size_t index = 0;   //!< 0-based position in this run
  std::size_t total = 0;
  RunPhase phase = RunPhase::kStarting;
  long cycles = 0;           //!< whole cycles at full amplitude so far
  long periods_recorded = 0;
  long periods_requested = 0;
  double steady_measure = 0.0;  //!< last cycle-to-cycle change / tolerance (< 1 agrees; inf before two cycles)
  std::optional<SteadyStateVerdict> steady;  //!< the steady-state test's figures, while it runs
  Margins margins;              //!< of each limit over the last interval
  double stroke = 0.0, force = 0.0;  //!< from the controller
};

//! One experiment of a run: a matrix entry and the attempt (a retry after an aborted recording
//! gets the label "<label>-<attempt>"; the session keeps both, the first aborted).
struct RunItem {
  MatrixEntry entry;
  int attempt = 1;
  std::string label() const;
};

//! The experiments of `matrix` that `so_far` (a resumed session) has not recorded complete or
//! not-steady, in matrix order, with the attempt after the aborted ones it holds.
std::vector<RunItem> RemainingExperiments(const std::vector<MatrixEntry>& matrix, const daq::Session& so_far);

enum class RunOutcome {
  kComplete,  //!< every experiment recorded
  kPaused,    //!< paused at an experiment boundary (operator, or a "hold" trip): resumable
  kAborted,   //!< a stop or interlock trip, or a device lost: the run stopped safely; resumable
};
std::string_view ToString(RunOutcome outcome);

struct RunReport {
  RunOutcome outcome = RunOutcome::kComplete;
  std::vector<std::string> complete, not_steady, aborted;  //!< session labels, by how they ended
  std::optional<Trip> trip;  //!< what ended or paused the run, when a detector or a device did
  std::string cause;         //!< in words, "" when complete
  std::vector<std::string> remaining;  //!< matrix labels not yet recorded
  bool disarmed = false;     //!< the controller was disarmed at the end
  //! Wall seconds the stream's samples arrived behind their own clock, at most (the lag detector's
  //! measure; a simulated rig's shows how close the machine came to not holding --speed).
  double largest_lag = 0.0;
  double lag_limit = 0.0;  //!< s, the lag detector's limit in force
  //! The top-out reference, when the run had one: the zero it found (recorded in /calibration)...
  std::optional<TopOutFit> top_out;
  //! ... or why it found none ("" when it found one or there was none); the run went on without.
  std::string top_out_failure;
};

//! Runs experiments on the rig. One thread calls Run; RequestPause/RequestStop may be called from
//! any thread or a signal handler.
class MatrixRunner {
 public:
  //! The acquisition must stream channels "stroke" and "force" ("pressure" optional). Throws
  //! std::invalid_argument when it does not or the options are invalid.
  MatrixRunner(daq::ActuatorController& controller, daq::AcquisitionModule& acquisition, daq::Recorder& recorder,
               SafetyConfig safety, RunnerOptions options);
  ~MatrixRunner();

  //! Runs the top-out reference when the options ask for it (an event and, when found, the zero in
  //! /calibration and its figures in /rig_run/top_out; when not found the run goes on without,
  //! saying so), then the items in order. Starts and stops the acquisition; sets the controller's watchdog;
  //! leaves the controller disarmed (hydraulics off, watchdog off) however the run ends. Every
  //! trip, pause, loss and abort is recorded as an event with its cause. Recorder errors (disk
  //! full) end the run aborted as well.
  RunReport Run(const std::vector<RunItem>& items);

  //! Pause after the experiment in progress (its recording completes), then end the run paused.
  void RequestPause() { pause_.store(true); }
  //! Stop now: the experiment in progress ramps out and is recorded aborted; the run ends paused.
  void RequestStop() { stop_.store(true); }

  std::function<void(const Progress&)> on_progress;
  //! Every event the run records (kind and text as in the session), as it is recorded.
  std::function<void(std::string_view kind, const std::string& text)> on_event;
  //! Every block read from the acquisition, on the runner's thread, before it is recorded: a
  //! consumer (the live monitor) must return at once and never wait on anything.
  std::function<void(const daq::AcquiredBlock&)> on_block;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::atomic<bool> pause_{false}, stop_{false};
};

}  // namespace strut::rig
