// A recorded session on the live monitor as a replay plays it (`strut replay --monitor`,
// docs/monitor.md "Replay"): the same feed, hub and page as a rig run, with the session's
// experiments as the matrix, the limits it recorded drawn into the traces, the steady-state test
// re-run on the replayed stream, and the events it recorded, each handed over when the replayed
// stream reaches the point where it was recorded.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "strut/daq/replay.h"
#include "strut/monitor/feed.h"
#include "strut/monitor/server.h"
#include "strut/rig/replay_steady_state.h"
#include "strut/rig/safety.h"

namespace strut::monitor {

//! What the page shows of a replay besides the stream: every experiment of the session as an
//! item of the matrix (label, frequency, amplitude, static position), the limits it recorded
//! (rig::RecordedLimits), the default steady-state tolerances (what the replayed stream is judged
//! with, as `strut replay` does).
MonitorSetup ReplaySetup(const daq::ReplayAcquisition& replay, std::string title);

//! An event of the session's log (/recording/events) and where in the replayed stream it goes
//! out: in experiment `experiment` (an index into the replay's experiments; their number: after
//! the last) once the stream has reached `time` s of that experiment's time axis (-inf: when the
//! experiment begins, +inf: when it ends).
struct ReplayedEvent {
  std::size_t experiment = 0;
  double time = 0.0;
  std::string kind, text;
};

//! The session's events in the order it recorded them, each placed in the replayed stream: an
//! event recorded during an experiment at its time there; one recorded between experiments when
//! the next experiment (by the recorded monotonic clock) begins, or after the last; without a
//! recorded clock, where the event before it went out. Never earlier than the event before it.
std::vector<ReplayedEvent> PlaceRecordedEvents(const daq::ReplayAcquisition& replay);

//! The observer that feeds the monitor from a replay: the blocks, a progress at every experiment
//! boundary and at most every 100 ms of wall time (the experiment, its periods played, the
//! steady-state figures of `steady`, the margins to the recorded limits), and the recorded events.
//! Runs on the replay's thread and never waits, as the rig runner's hooks.
class ReplayMonitor : public daq::ReplayObserver {
 public:
  //! `steady` (may be nullptr): the steady-state detector on the same stream; this observer calls
  //! it first, so `strut replay` prints the verdicts the page showed.
  ReplayMonitor(const daq::ReplayAcquisition& replay, rig::SteadyStateOnReplay* steady);

  //! The feed the monitor's server takes from: the first experiment's channels, at most 2000
  //! points a wall second of the fastest experiment at the replay's speed.
  MonitorFeed& feed() { return feed_; }

  void BeginExperiment(const daq::ReplayedExperiment& x) override;
  void Block(const daq::ReplayedExperiment& x, const daq::AcquiredBlock& b) override;
  void EndExperiment(const daq::ReplayedExperiment& x) override;
  //! After the last experiment: the events recorded after it, the progress "done", and
  //! everything handed over (MonitorFeed::Flush).
  void Finish();

 private:
  std::size_t IndexOf(const daq::ReplayedExperiment& x) const;
  //! Hands over the events due by (experiment, time).
  void EventsUpTo(std::size_t experiment, double time);
  void SendProgress(rig::RunPhase phase);

  const daq::ReplayAcquisition& replay_;
  rig::SteadyStateOnReplay* steady_;
  MonitorFeed feed_;
  rig::SafetyConfig limits_;
  std::vector<ReplayedEvent> events_;
  std::size_t next_event_ = 0;
  // The experiment playing now.
  std::size_t index_ = 0;
  std::optional<rig::SafetyMonitor> margins_;
  std::optional<long> samples_per_period_;
  std::vector<int> order_;      // per feed channel, its place in the experiment's blocks (-1: not there)
  bool same_order_ = true;      // the blocks' channels are the feed's, in its order
  int stroke_channel_ = -1, force_channel_ = -1;
  std::int64_t first_ns_ = -1;  // its first sample's time on the stream
  std::size_t played_ = 0;      // its samples played so far
  double stroke_ = 0.0, force_ = 0.0;
  double last_progress_ = -1.0;  // feed wall s
};

}  // namespace strut::monitor
