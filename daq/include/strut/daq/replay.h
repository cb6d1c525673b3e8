// Replay of a recorded session (docs/replay.md): ReplayAcquisition plays a session's experiments
// back through the acquisition interface as the rig's stream delivered them (timestamps, SI
// values, counts, calibration, sequence and quality), paced by a speed factor or as fast as
// possible. PlayReplay records it through the path a rig run records through (AcquiredExperiment,
// RecordedBlock, Recorder); SendReplay sends it as CAN frames to a transport, where any
// CanAcquisition receives it. Recording a replay reproduces the session's samples bit for bit.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "strut/daq/acquisition.h"
#include "strut/daq/can_acquisition.h"
#include "strut/daq/recorder.h"
#include "strut/daq/session.h"

namespace strut::daq {

struct ReplayOptions {
  //! Recorded seconds played per wall second (1: as the rig delivered them); 0: as fast as
  //! possible. Finite and >= 0.
  double speed = 0.0;
  //! Sample sets per block when the stream flows (0: sample_rate / 100, at least 1), as
  //! CanAcquisition delivers them.
  std::size_t block_sets = 0;
  //! False with a message naming the option when a value is out of range.
  bool IsValid(std::string* error) const;
  //! The pace as the replay's event and the command say it: "at 2x" or "as fast as possible".
  std::string pace() const;
};

//! One experiment of the session as the replay plays it.
struct ReplayedExperiment {
  //! The recorded experiment without samples: label, kind, attributes (not the recorder's own:
  //! recording_end, monotonic_start_ns, utc_start, requested_periods), channels (name, units,
  //! reference) of the stream only. `periods`: the periods requested (an aborted one's
  //! requested_periods), as a descriptor gives them.
  Experiment header;
  StreamDescription stream;  //!< what the stream carries while it plays: rate, channels, calibrations
  EndStatus end = EndStatus::kComplete;  //!< how the recording ended it
  long periods = 0;                      //!< whole periods it was stored with (0 when aborted)
  std::size_t samples = 0;
  //! Per stream channel: its counts are the session's `<channel>_counts` (with the calibration of
  //! /recording/calibration); else they are derived from the SI values (docs/replay.md).
  std::vector<bool> recorded_counts;
  bool recorded_sequence = false;  //!< the session's `sequence` channel gives the sets' indices
  bool recorded_status = false;    //!< the session's `status` channel gives the blocks' quality
  //! Every time lies on whole nanoseconds from the first (t = k / 1e9 exactly), so a recording of
  //! the replay reproduces the time axis bit for bit; else to within half a nanosecond.
  bool exact_time = true;
};

//! A recorded session as an acquisition module. Not thread-safe, like every module.
//!
//! The stream: experiments back to back in session order, each sample at the Start time plus its
//! place on the session's time axes (in whole ns), whatever the pace. A block never spans two
//! experiments, a change of the recorded status or a jump of the recorded sequence. Experiment
//! boundaries: next_experiment() names the experiment the next block belongs to; after Read
//! returned the last block of one it names the following one (and description() describes
//! that); finished() once the last block of the last one was returned, after which Read returns
//! empty blocks at once.
class ReplayAcquisition : public AcquisitionModule {
 public:
  //! Throws SessionError naming the file, experiment and channel when a counts, sequence or
  //! status channel holds what no recorder wrote (not whole numbers, out of range), or when a
  //! calibration is malformed; std::invalid_argument naming the option for bad options.
  explicit ReplayAcquisition(Session session, ReplayOptions options = {});
  ~ReplayAcquisition() override;
  ReplayAcquisition(const ReplayAcquisition&) = delete;
  ReplayAcquisition& operator=(const ReplayAcquisition&) = delete;
  //! Reads the session at `path` (ReadSession: the contract check) and replays it.
  static std::unique_ptr<ReplayAcquisition> Open(const std::string& path, ReplayOptions options = {});

  //! The stream of next_experiment() (of the last experiment once finished).
  const StreamDescription& description() const override;
  void Start() override;
  void Stop() override;
  //! The next block: at once when as fast as possible; paced, when its last sample is due (never
  //! later than `timeout` from now: then the sets due by then, or an empty block).
  AcquiredBlock Read(std::chrono::nanoseconds timeout) override;
  const AcquisitionStats& stats() const override { return stats_; }

  const Session& session() const { return session_; }
  const std::vector<ReplayedExperiment>& experiments() const { return experiments_; }
  const ReplayOptions& options() const { return options_; }
  //! Index into experiments() of the experiment the next block belongs to.
  std::size_t next_experiment() const { return current_; }
  bool finished() const { return current_ >= experiments_.size(); }
  //! Recorded seconds of the whole stream (experiments back to back).
  double recorded_seconds() const;
  //! The counts the stream carries for stream channel `channel` of experiment `experiment`.
  const std::vector<std::int32_t>& counts(std::size_t experiment, std::size_t channel) const;

 private:
  struct Track;    // one experiment's samples as the stream sends them
  struct Sources;  // the session's stored calibrations, counts channels and value ranges
  //! Experiment `k` of the session into experiments_ and tracks_, its stream time from `base_ns`
  //! (moved past its last set).
  void AddExperiment(const Sources& sources, std::size_t k, std::int64_t& base_ns);
  //! The stream channels of experiment `k`: header channel, calibration and counts of each.
  void AddStreamChannels(const Sources& sources, std::size_t k, ReplayedExperiment& x, Track& t) const;
  //! The experiment's times as whole ns from `base_ns`; SessionError when a step is below 1 ns.
  static void ReadTimeAxis(const std::string& file, const Experiment& e, std::int64_t base_ns, ReplayedExperiment& x,
                           Track& t);
  std::size_t RunLength(const Track& t, std::size_t from) const;
  std::int64_t DueNs(const Track& t, std::size_t i) const;

  Session session_;
  ReplayOptions options_;
  std::vector<ReplayedExperiment> experiments_;
  std::vector<Track> tracks_;
  AcquisitionStats stats_;
  bool running_ = false;
  std::size_t current_ = 0;    //!< experiment of the next set
  std::size_t position_ = 0;   //!< its next set
  std::uint64_t next_index_ = 0;  //!< index of the next set when the session has no sequence
  std::int64_t start_ns_ = 0;  //!< monotonic time of Start: stream time 0
};

//! Watches a replayed stream experiment by experiment: the hook for what re-runs on replay (the
//! steady-state detector of rig/steady_state.h, segmentation). The blocks are those a recorder
//! gets.
class ReplayObserver {
 public:
  virtual ~ReplayObserver() = default;
  virtual void BeginExperiment(const ReplayedExperiment& experiment) = 0;
  virtual void Block(const ReplayedExperiment& experiment, const AcquiredBlock& block) = 0;
  virtual void EndExperiment(const ReplayedExperiment& experiment) = 0;
};

//! The descriptor a recording of a replayed experiment begins with: AcquiredExperiment over its
//! stream, raw counts, sequence and status kept only where the session had them, so that the
//! recording holds the session's channels and no others.
ExperimentDescriptor RecordingDescriptor(const ReplayedExperiment& experiment);
//! RecordedBlock(block) with what RecordingDescriptor(experiment) keeps.
SampleBlock RecordingBlock(const ReplayedExperiment& experiment, const AcquiredBlock& block);
//! Metadata of a recording of the replay: the session's serial, rig, profile and root groups (its
//! /truth), and from its /recording group the operator, matrix and limits.
RecordingMetadata ReplayMetadata(const Session& session);

//! What a whole replay took.
struct ReplayFigures {
  std::size_t experiments = 0;
  std::uint64_t sample_sets = 0;
  double recorded_s = 0.0;  //!< recorded time played
  double wall_s = 0.0;
};

//! Plays the whole replay (Start to Stop): every block to `observer` and, when given, into
//! `recorder`, experiment by experiment, each ended as the session ended it.
ReplayFigures PlayReplay(ReplayAcquisition& replay, Recorder* recorder, ReplayObserver* observer = nullptr);

//! The CAN stream a replay sends (docs/replay.md "Over CAN"), which is also what its receiver is
//! configured with: the stream's channels and calibration (one for the whole session), the rate
//! on the wire (the recorded rate times the speed: a receiver checks frames against a clock at its
//! rate), classic frames when that fits half of a 1 Mbit/s bus, else CAN FD. Throws SessionError
//! naming the experiment and channel when experiments differ in rate, channels or calibration,
//! or when a count does not fit 16 bits; std::invalid_argument when the replay has no pace
//! (speed 0).
CanAcquisitionOptions ReplayCanOptions(const ReplayAcquisition& replay, std::uint8_t module = 1);

//! Plays the whole replay as frames of `options` (ReplayCanOptions) into `transport`: every
//! sample set's counts, indices consecutive from 0, a status frame every tenth of a second of
//! samples. Throws DeviceError when the transport fails.
ReplayFigures SendReplay(ReplayAcquisition& replay, std::unique_ptr<CanTransport> transport,
                         const CanAcquisitionOptions& options, ReplayObserver* observer = nullptr);

}  // namespace strut::daq
