// Streaming, crash-safe recording of a session (docs/recording.md): producers hand over blocks
// of samples as they arrive; one writer thread appends them to a journal beside the session
// (`<session>.journal`) and makes it durable at least once a second; Close turns the journal
// into the contract file (session.h, WriteSession). After a crash, kill -9 or power cut,
// RecoverJournal (`strut recover`) does the same with what the journal kept, the experiment in
// progress marked aborted.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "strut/daq/acquisition.h"
#include "strut/daq/session.h"

namespace strut::daq {

//! A recording error a user or the machine can cause (bad call, disk full, queue full). what()
//! names the journal or session file and, where it applies, the experiment and channel.
class RecorderError : public SessionError {
 public:
  using SessionError::SessionError;
};

//! A channel whose raw counts are stored beside its SI samples (as `<channel>_counts`).
struct RawChannel {
  std::string channel;  //!< name of a channel of the experiment
  Calibration calibration;  //!< counts to SI; range_min..range_max is the transducer's full scale
};

//! Session-wide metadata, written once at Open.
struct RecordingMetadata {
  std::string damper_serial;  //!< required
  std::string rig;            //!< required: rig or simulator name
  std::string operator_name;
  std::string software_version;  //!< empty: this strut's version
  std::string matrix;            //!< the test matrix: its file's text, or a name ("standard")
  std::map<std::string, double> limits;  //!< name -> SI value, e.g. "stroke_max" -> 0.25
  std::string profile = std::string(kDamperProfile);
  std::vector<MetadataGroup> groups;  //!< further root groups (e.g. a simulator's /truth)
};

//! What an experiment is, given at BeginExperiment.
struct ExperimentDescriptor {
  //! label, kind, sample_rate, the kind's attributes, extra attributes and the channels (name,
  //! units, reference; no samples). `periods` is the number requested (0: unknown); status and
  //! the final periods come with EndExperiment.
  Experiment header;
  std::vector<RawChannel> raw;  //!< channels recorded with raw counts, in block order
  bool sequence = false;        //!< blocks carry the acquisition's sequence number per sample
  bool status = false;          //!< blocks carry a status (quality) word per sample
};

//! Consecutive samples of the open experiment. Every vector holds size() values.
struct SampleBlock {
  //! Per sample, increasing: CLOCK_MONOTONIC (std::chrono::steady_clock on Linux) in ns, the
  //! clock the recorder pairs with UTC. `time` in the file is this minus the first sample's.
  std::vector<std::int64_t> monotonic_ns;
  std::vector<std::vector<double>> values;       //!< SI, one per header channel, in its order
  std::vector<std::vector<std::int32_t>> counts;  //!< one per RawChannel, in descriptor order
  std::vector<std::uint64_t> sequence;           //!< when the descriptor says so
  std::vector<std::uint32_t> status;             //!< when the descriptor says so
  std::size_t size() const { return monotonic_ns.size(); }
};

//! The descriptor of an experiment recorded from an acquisition stream: `header` (label, kind,
//! attributes; its channels are replaced) gets the stream's channels in the stream's order, with
//! their names and units, `pressure_reference` ("gauge" or "absolute") for a channel named
//! "pressure", and sample_rate the stream's unless set. Every channel keeps its raw counts and
//! calibration; the sequence index and the quality word are kept per sample.
ExperimentDescriptor AcquiredExperiment(Experiment header, const StreamDescription& stream,
                                        std::string_view pressure_reference = "gauge");

//! The recorder's block for the sample sets [begin, end) of an acquired block (end clipped to its
//! size): timestamps, SI values and counts as they came, the sample set's index since Start as
//! its sequence and the block's Quality flags as its status. For AcquiredExperiment descriptors.
SampleBlock RecordedBlock(const AcquiredBlock& block, std::size_t begin = 0,
                          std::size_t end = static_cast<std::size_t>(-1));

//! A block of a stream that runs `speed` times faster than the time it records (a simulated rig
//! served at --speed X) put on the recorded clock: every timestamp t becomes
//! origin + (t - origin) * speed, so that its steps are 1 / the recorded sample rate as the
//! Recorder requires (speed 1 leaves the block as it is).
void ToRecordedTime(std::span<std::int64_t> times_ns, std::int64_t origin_ns, double speed);
void ToRecordedTime(SampleBlock& block, std::int64_t origin_ns, double speed);

//! How an experiment ended. kNotSteady: recorded in full but the response never settled
//! (stored as status "complete" with recording_end = "not-steady").
enum class EndStatus { kComplete, kAborted, kNotSteady };
std::string_view ToString(EndStatus status);

struct RecorderOptions {
  //! Overwrite an existing session file or journal at the path. Default false: Open refuses.
  bool force = false;
  //! Longest time written data stays unsynced (fdatasync). 1 ms .. 1 s; default 250 ms, so a
  //! power cut loses at most the last quarter second plus the time of one sync.
  std::chrono::milliseconds sync_interval{250};
  //! Bytes handed over but not yet written that the queue holds at most (default 64 MiB: 40 s of
  //! 4 channels at 50 kHz with counts). When full, Append waits up to queue_full_timeout for the
  //! writer; then it throws and the recording is failed: a dropped block would break the
  //! constant-rate time axis, so the recorder never drops data silently.
  std::size_t queue_limit_bytes = std::size_t{64} << 20;
  std::chrono::milliseconds queue_full_timeout{2000};
  //! How often the writer records a (monotonic, UTC) clock pair while running.
  std::chrono::milliseconds clock_pair_interval{10000};
  //! How Close writes the contract file (gzip level, chunks).
  WriteOptions write;

  //! False with a message naming the option when a value is out of range.
  bool IsValid(std::string* error) const;
};

//! Figures of a recording so far.
struct RecorderStats {
  std::uint64_t samples = 0;          //!< handed over by Append
  std::uint64_t bytes_handed = 0;     //!< journal bytes queued by the callers
  std::uint64_t bytes_written = 0;    //!< journal bytes written by the writer thread
  std::uint64_t bytes_synced = 0;     //!< journal bytes known durable
  std::uint64_t syncs = 0;
  std::size_t max_queue_bytes = 0;    //!< high-water mark of the queue
  double longest_sync_gap_s = 0.0;    //!< longest time written data waited for its sync
};

//! Where the journal bytes go: a file, or in tests a fake that records writes and syncs and
//! injects faults. Used by the writer thread only. Every method throws RecorderError on failure.
class JournalSink {
 public:
  virtual ~JournalSink() = default;
  virtual void Write(std::span<const std::byte> bytes) = 0;
  //! Makes everything written so far durable.
  virtual void Sync() = 0;
  virtual void Close() = 0;
};

//! The journal file (O_APPEND, fdatasync). Creates it; an existing one only with `force`.
std::unique_ptr<JournalSink> CreateJournalFile(const std::string& journal_path, bool force);

//! `<session_path>.journal`.
std::string JournalPath(const std::string& session_path);

//! Records one session. Thread-safe: any number of producer threads may call it.
class Recorder {
 public:
  //! Starts a recording into `session_path`: creates its journal (RecorderError when the session
  //! or its journal exists and not options.force, when the folder is not writable, or when the
  //! metadata lack damper_serial or rig). `sink` replaces the journal file (tests); it must
  //! leave the journal's bytes at JournalPath(session_path).
  static Recorder Open(const std::string& session_path, const RecordingMetadata& metadata,
                       const RecorderOptions& options = {},
                       std::unique_ptr<JournalSink> sink = nullptr);
  //! Goes on recording into the session whose journal `<session_path>.journal` is there (kept by
  //! Close(true), or left by a crash or kill -9): reads it as `strut recover` does, cuts off a torn
  //! tail, ends an experiment that was in progress as aborted (event "recovered"), and appends a
  //! Resume record (event "resumed" with `text`, a new clock pair) after which new experiments
  //! follow. The session so far (what Close would write now) goes to `so_far` when given.
  //! RecorderError when there is no journal (a session closed without keeping it cannot be resumed)
  //! or it is not a recording journal. options.force is not used.
  static Recorder Resume(const std::string& session_path, const RecorderOptions& options = {},
                         const std::string& text = "recording resumed", Session* so_far = nullptr);
  Recorder(Recorder&&) noexcept;
  Recorder& operator=(Recorder&&) noexcept;
  //! Closes like Close() when still open (errors are logged, the journal then stays).
  ~Recorder();

  //! Starts an experiment. Throws when one is open, the label was used, or the header breaks the
  //! contract (the same checks as Validate, naming the experiment and item).
  void BeginExperiment(const ExperimentDescriptor& descriptor);
  //! Queues a block of the open experiment. Throws on a malformed block (sizes, timestamps not
  //! increasing or a step more than 50 % off 1/sample_rate: a gap, which the contract's constant
  //! rate forbids; end the experiment aborted and begin another), NaN/Inf), when no experiment is open, when the queue stays full, or when the
  //! writer failed (disk full): the error names the journal, experiment and channel.
  void Append(const SampleBlock& block);
  //! Records an event (trip, abort, pause, resume, note, ...) at a monotonic time.
  void Event(std::int64_t monotonic_ns, std::string_view kind, std::string_view text);
  //! Adds a root metadata group during the recording (e.g. the rig runner's per-cycle summaries):
  //! merged into a group of that name if there is one (attributes and same-named subgroups
  //! replaced, others appended). Throws for "experiments", "recording" or a name with '/'.
  void AddMetadata(const MetadataGroup& group);
  //! Ends the open experiment. `periods` (periodic, complete): whole periods recorded, default
  //! the requested ones; the sample count must match (contract). Aborted experiments are stored
  //! with periods = 0 and `requested_periods`.
  void EndExperiment(EndStatus status, std::optional<long> periods = std::nullopt);
  //! Ends an open experiment as aborted, drains and syncs the journal, writes the session file
  //! and removes the journal, or keeps it with `keep_journal` so that Resume can go on (a paused
  //! or stopped run). When anything failed the journal is kept and RecorderError says so.
  void Close(bool keep_journal = false);

  RecorderStats stats() const;
  const std::string& session_path() const;
  const std::string& journal_path() const;

 private:
  struct Impl;
  explicit Recorder(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

//! What a journal held when it was read.
struct JournalReport {
  std::size_t records = 0;
  std::uint64_t bytes_read = 0;       //!< valid bytes, header included
  std::uint64_t bytes_discarded = 0;  //!< a torn or damaged tail (nothing after a clean Close)
  bool closed = false;                //!< the recording ended with Close
  std::vector<std::string> aborted;   //!< experiments that were in progress at the cut
  std::vector<std::string> dropped;   //!< experiments without a single sample (not written)
  std::string in_progress;            //!< the experiment open at the journal's end ("" when none)
  std::uint64_t samples = 0;
};

//! Reads a journal into the session Close would write, tolerating a torn or damaged tail:
//! everything up to the last intact record is kept, an experiment in progress is aborted.
//! Throws RecorderError when the file is not a journal or holds no intact header.
Session ReadJournal(const std::string& journal_path, JournalReport* report = nullptr);

//! Writes the session a journal holds to `session_path` (never over an existing file unless
//! `force`, never over the journal). The journal itself is not modified.
JournalReport RecoverJournal(const std::string& journal_path, const std::string& session_path,
                             bool force, const WriteOptions& options = {});

}  // namespace strut::daq
