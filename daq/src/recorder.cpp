// The streaming recorder: producers validate and serialise on their own thread and queue whole
// journal records; one writer thread appends them to the journal and syncs it at least every
// sync_interval; Close converts the journal into the contract file.
#include "strut/daq/recorder.h"

#include <fcntl.h>
#include <spdlog/fmt/fmt.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <filesystem>
#include <mutex>
#include <set>
#include <thread>

#include "journal.h"
#include "strut/daq/atomic_file.h"
#include "session_check.h"

#ifndef STRUT_VERSION
#define STRUT_VERSION "unknown"
#endif

namespace strut::daq {

namespace {

using Clock = std::chrono::steady_clock;

// The journal on disk: O_APPEND writes, fdatasync.
class JournalFile final : public JournalSink {
 public:
  JournalFile(std::string path, int fd) : path_(std::move(path)), fd_(fd) {}
  ~JournalFile() override {
    if (fd_ >= 0) ::close(fd_);
  }

  void Write(std::span<const std::byte> bytes) override {
    std::size_t done = 0;
    while (done < bytes.size()) {
      const ssize_t n = ::write(fd_, bytes.data() + done, bytes.size() - done);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) Fail("writing", n < 0 ? errno : EIO);
      done += static_cast<std::size_t>(n);
    }
  }

  void Sync() override {
    if (::fdatasync(fd_) != 0) Fail("syncing", errno);
  }

  void Close() override {
    if (fd_ < 0) return;
    const int fd = std::exchange(fd_, -1);
    if (::close(fd) != 0) Fail("closing", errno);
  }

 private:
  [[noreturn]] void Fail(const char* what, int error) const {
    throw RecorderError(fmt::format("{}: cannot write: {}: {}", path_, what, std::strerror(error)));
  }

  std::string path_;
  int fd_;
};

bool ValidName(std::string_view name) {
  return !name.empty() && name != "." && name.find('/') == std::string_view::npos;
}

// A metadata group the caller may put at the root: a name, and not one the recorder writes itself.
bool AllowedRootGroup(std::string_view name) { return ValidName(name) && name != "experiments" && name != "recording"; }

}  // namespace

bool RecorderOptions::IsValid(std::string* error) const {
  auto fail = [&](std::string message) {
    if (error != nullptr) *error = std::move(message);
    return false;
  };
  if (sync_interval.count() < 1 || sync_interval.count() > 1000) {
    return fail(fmt::format("sync_interval {} ms is outside 1..1000 ms", sync_interval.count()));
  }
  if (queue_limit_bytes < 1024) return fail(fmt::format("queue_limit_bytes {} is below 1024", queue_limit_bytes));
  if (queue_full_timeout.count() < 0) return fail("queue_full_timeout is negative");
  if (clock_pair_interval.count() < 1) return fail("clock_pair_interval must be >= 1 ms");
  if (write.gzip_level < 0 || write.gzip_level > 9) {
    return fail(fmt::format("write.gzip_level {} is outside 0..9", write.gzip_level));
  }
  return true;
}

// An existing journal opened to append (Resume), after cutting it to `keep_bytes` (a torn tail).
std::unique_ptr<JournalSink> ReopenJournalFile(const std::string& journal_path, std::uint64_t keep_bytes) {
  const int fd = ::open(journal_path.c_str(), O_WRONLY | O_APPEND | O_CLOEXEC);
  if (fd < 0) {
    throw RecorderError(fmt::format("{}: cannot reopen the journal: {}", journal_path, std::strerror(errno)));
  }
  if (::ftruncate(fd, static_cast<off_t>(keep_bytes)) != 0 || ::fdatasync(fd) != 0) {
    const int error = errno;
    ::close(fd);
    throw RecorderError(fmt::format("{}: cannot cut the journal's torn tail at byte {}: {}", journal_path, keep_bytes,
                                    std::strerror(error)));
  }
  return std::make_unique<JournalFile>(journal_path, fd);
}

std::unique_ptr<JournalSink> CreateJournalFile(const std::string& journal_path, bool force) {
  const int flags = O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC | (force ? O_TRUNC : O_EXCL);
  const int fd = ::open(journal_path.c_str(), flags, 0666);
  if (fd < 0) {
    const int error = errno;
    throw RecorderError(fmt::format(
        "{}: cannot create the journal: {}{}", journal_path, std::strerror(error),
        error == EEXIST ? " (left by an earlier recording: `strut recover` it, or record with force)" : ""));
  }
  SyncDirectoryOf(journal_path);
  return std::make_unique<JournalFile>(journal_path, fd);
}

// The experiment being recorded, as the producers see it.
struct OpenExperiment {
  std::string label;
  ExperimentKind kind = ExperimentKind::kPeriodic;
  double sample_rate = 0.0;
  double frequency = 0.0;
  long requested_periods = 0;
  std::vector<std::string> channels;
  std::size_t raw = 0;
  bool sequence = false;
  bool status = false;
  std::uint64_t samples = 0;
  std::int64_t last_ns = 0;
};

struct Recorder::Impl {
  std::string session_path;
  std::string journal_path;
  RecordingMetadata metadata;
  RecorderOptions options;
  std::unique_ptr<JournalSink> sink;

  // Held for the whole of each API call, so calls of several producers never interleave (an End
  // while an Append waits for queue space would put a block outside its experiment).
  std::mutex api;
  mutable std::mutex mutex;  // the state below; the writer thread takes only this one
  std::condition_variable work;   // the writer: records queued, or stop
  std::condition_variable space;  // producers: the queue has room again
  std::deque<std::vector<std::byte>> queue;
  std::size_t queued_bytes = 0;
  bool stopping = false;
  bool closed = false;
  std::string failure;  // first error of the writer or the queue; the recording is failed
  std::optional<OpenExperiment> open;
  std::set<std::string> labels;
  RecorderStats stats;
  std::thread writer;

  [[noreturn]] void Throw(std::string_view what) const {
    throw RecorderError(fmt::format("{}: {}", session_path, what));
  }
  [[noreturn]] void ThrowIn(std::string_view what) const {
    throw RecorderError(fmt::format("{}: experiment '{}': {}", session_path, open->label, what));
  }
  void CheckUsable() const {
    if (closed || stopping) Throw("the recorder is closed");
    if (!failure.empty()) throw RecorderError(failure);
  }

  // Queues a record, waiting while the queue is full (policy: RecorderOptions::queue_limit_bytes).
  void Enqueue(std::unique_lock<std::mutex>& lock, std::vector<std::byte> record) {
    const std::size_t n = record.size();
    const auto fits = [&] { return queued_bytes == 0 || queued_bytes + n <= options.queue_limit_bytes || !failure.empty(); };
    if (!space.wait_for(lock, options.queue_full_timeout, fits)) {
      failure = fmt::format(
          "{}: recording failed: the writer could not keep up (queue full at {} bytes for {} ms; "
          "disk too slow?); a block was refused",
          journal_path, queued_bytes, options.queue_full_timeout.count());
      throw RecorderError(failure);
    }
    if (!failure.empty()) throw RecorderError(failure);
    queue.push_back(std::move(record));
    queued_bytes += n;
    stats.bytes_handed += n;
    stats.max_queue_bytes = std::max(stats.max_queue_bytes, queued_bytes);
    work.notify_one();
  }

  void WriterLoop() {
    // Written but not yet synced since then (a plain time point: GCC 12 warns about an optional).
    bool unsynced = false;
    Clock::time_point unsynced_since{};
    std::uint64_t unsynced_bytes = 0;
    Clock::time_point next_clock = Clock::now() + options.clock_pair_interval;
    bool failed = false;
    std::unique_lock lock(mutex);
    for (;;) {
      Clock::time_point deadline = next_clock;
      if (unsynced) deadline = std::min(deadline, unsynced_since + options.sync_interval);
      work.wait_until(lock, deadline, [&] { return !queue.empty() || stopping; });
      std::deque<std::vector<std::byte>> batch;
      batch.swap(queue);
      const bool stop = stopping;
      lock.unlock();

      std::size_t batch_bytes = 0;
      std::uint64_t written = 0;
      std::string error;
      const Clock::time_point started = Clock::now();
      try {
        for (const auto& record : batch) {
          batch_bytes += record.size();
          if (failed) continue;  // after a failure, queued records are dropped (the callers know)
          sink->Write(record);
          written += record.size();
        }
        if (!failed && Clock::now() >= next_clock) {
          const auto record = journal::Record(
              journal::RecordType::kClock, journal::ClockPayload(journal::MonotonicNowNs(), journal::UtcNowNs()));
          sink->Write(record);
          written += record.size();
          next_clock = Clock::now() + options.clock_pair_interval;
        }
        if (written > 0 && !unsynced) {
          unsynced = true;
          unsynced_since = started;
        }
        unsynced_bytes += written;
        if (!failed && unsynced && (stop || Clock::now() - unsynced_since >= options.sync_interval)) {
          sink->Sync();
          const double gap = std::chrono::duration<double>(Clock::now() - unsynced_since).count();
          lock.lock();
          stats.syncs += 1;
          stats.bytes_synced += unsynced_bytes;
          stats.longest_sync_gap_s = std::max(stats.longest_sync_gap_s, gap);
          lock.unlock();
          unsynced = false;
          unsynced_bytes = 0;
        }
      } catch (const std::exception& e) {
        // The writer thread's boundary, before a sink the caller may have written: whatever it
        // throws becomes the recorder's failure, which the next Append and Close throw to the
        // producers as RecorderError (a throw out of this thread would end the process).
        error = e.what();
        failed = true;
      }

      lock.lock();
      stats.bytes_written += written;
      queued_bytes -= batch_bytes;
      if (!error.empty() && failure.empty()) {
        failure = fmt::format("{}: recording failed: {}", session_path, error);
        spdlog::error("{}", failure);
      }
      space.notify_all();
      if (stop && queue.empty()) break;
    }
  }

  // Checks the header against the contract as a one-sample experiment (the final status and
  // periods are not known yet, so as an aborted one).
  void CheckHeader(const ExperimentDescriptor& d) const {
    const Experiment& h = d.header;
    const std::string where = fmt::format("{}: experiment '{}'", session_path, h.label);
    if (!ValidName(h.label)) Throw(fmt::format("experiment label '{}' is not a valid name", h.label));
    if (labels.count(h.label) != 0) Throw(fmt::format("experiment '{}' was recorded already", h.label));
    if (h.periods < 0) throw RecorderError(fmt::format("{}: requested periods {} < 0", where, h.periods));
    Session probe;
    probe.source_path = session_path;
    probe.created_utc = "2000-01-01T00:00:00Z";
    probe.damper_serial = metadata.damper_serial;
    probe.rig = metadata.rig;
    probe.profile = metadata.profile;
    Experiment e = h;
    e.status = "aborted";
    e.periods = 0;
    e.time = {0.0};
    std::set<std::string> names;
    for (Channel& c : e.channels) {
      c.samples = {0.0};
      names.insert(c.name);
    }
    std::set<std::string> raw;
    for (const RawChannel& r : d.raw) {
      if (names.count(r.channel) == 0) {
        throw RecorderError(fmt::format("{}: raw counts of '{}', which is not a channel of it", where, r.channel));
      }
      if (!raw.insert(r.channel).second) {
        throw RecorderError(fmt::format("{}: raw counts of '{}' given twice", where, r.channel));
      }
      if (!(std::isfinite(r.calibration.gain) && r.calibration.gain != 0.0 && std::isfinite(r.calibration.offset))) {
        throw RecorderError(fmt::format("{}: channel '{}': calibration gain must be finite and non-zero, offset finite",
                                        where, r.channel));
      }
      e.channels.push_back({r.channel + "_counts", "1", "", {0.0}});
    }
    if (d.sequence) e.channels.push_back({"sequence", "1", "", {0.0}});
    if (d.status) e.channels.push_back({"status", "1", "", {0.0}});
    for (const char* name : {"recording_end", "monotonic_start_ns", "utc_start", "requested_periods"}) {
      if (h.extra_attributes.count(name) != 0) {
        throw RecorderError(fmt::format("{}: extra attribute '{}' is the recorder's own", where, name));
      }
    }
    probe.experiments.push_back(std::move(e));
    const std::vector<std::string> defects = Validate(probe);
    if (!defects.empty()) {
      throw RecorderError(fmt::format("{}: experiment '{}' not begun:\n{}", session_path, h.label,
                                      fmt::join(defects, "\n")));
    }
  }

  void CheckBlock(const SampleBlock& b) const {
    const OpenExperiment& e = *open;
    const std::size_t n = b.size();
    if (b.values.size() != e.channels.size()) {
      ThrowIn(fmt::format("block has {} channels, the experiment {}", b.values.size(), e.channels.size()));
    }
    for (std::size_t k = 0; k < b.values.size(); ++k) {
      if (b.values[k].size() != n) {
        ThrowIn(fmt::format("channel '{}': {} samples in a block of {} timestamps", e.channels[k],
                            b.values[k].size(), n));
      }
      const auto bad = std::find_if(b.values[k].begin(), b.values[k].end(), [](double v) { return !std::isfinite(v); });
      if (bad != b.values[k].end()) {
        ThrowIn(fmt::format("channel '{}': NaN/Inf at sample {} of the experiment (mark bad samples in the "
                            "status word instead)",
                            e.channels[k], e.samples + (bad - b.values[k].begin())));
      }
    }
    if (b.counts.size() != e.raw) ThrowIn(fmt::format("block has {} raw channels, the experiment {}", b.counts.size(), e.raw));
    for (const auto& c : b.counts) {
      if (c.size() != n) ThrowIn(fmt::format("raw counts: {} samples in a block of {} timestamps", c.size(), n));
    }
    if (b.sequence.size() != (e.sequence ? n : 0)) {
      ThrowIn(fmt::format("sequence: {} values in a block of {} (expected {})", b.sequence.size(), n, e.sequence ? n : 0));
    }
    if (b.status.size() != (e.status ? n : 0)) {
      ThrowIn(fmt::format("status: {} values in a block of {} (expected {})", b.status.size(), n, e.status ? n : 0));
    }
    // The contract's constant rate: no step more than 50 % off 1/sample_rate (the reader's rule),
    // so whatever part of the experiment a crash leaves is a valid file.
    const double period_ns = 1e9 / e.sample_rate;
    std::int64_t previous = e.last_ns;
    for (std::size_t i = 0; i < n; ++i) {
      const bool first = e.samples == 0 && i == 0;
      if (!first && b.monotonic_ns[i] <= previous) {
        ThrowIn(fmt::format("timestamps not increasing at sample {} ({} ns after {} ns)", e.samples + i,
                            b.monotonic_ns[i], previous));
      }
      if (!first && std::abs(static_cast<double>(b.monotonic_ns[i] - previous) - period_ns) > 0.5 * period_ns) {
        ThrowIn(fmt::format("sample {} comes {} ns after the previous one, 1/sample_rate is {:.0f} ns: lost or "
                            "repeated samples (the contract wants a constant rate: end the experiment aborted "
                            "and begin another)",
                            e.samples + i, b.monotonic_ns[i] - previous, period_ns));
      }
      previous = b.monotonic_ns[i];
    }
  }

  void StopAndJoin() {
    {
      std::lock_guard lock(mutex);
      stopping = true;
      work.notify_one();
    }
    if (writer.joinable()) writer.join();
  }

  void Close(bool keep_journal) {
    std::lock_guard call(api);
    std::unique_lock lock(mutex);
    if (closed) return;
    if (stopping) Throw("the recorder is closing");
    if (failure.empty()) {
      try {
        if (open) {
          Enqueue(lock, journal::Record(journal::RecordType::kEvent,
                                        journal::EventPayload(journal::MonotonicNowNs(), "aborted",
                                                              fmt::format("experiment '{}' still open at Close", open->label))));
          Enqueue(lock, journal::Record(journal::RecordType::kEnd, journal::EndPayload(EndStatus::kAborted, 0)));
          open.reset();
        }
        Enqueue(lock, journal::Record(journal::RecordType::kClose, journal::ClosePayload(UtcNowIso8601())));
      } catch (const RecorderError&) {
        // The failure is recorded; what the journal holds is converted below all the same.
      }
    }
    lock.unlock();
    StopAndJoin();
    lock.lock();
    closed = true;
    std::string failed = failure;
    lock.unlock();
    try {
      sink->Close();
    } catch (const RecorderError& e) {
      if (failed.empty()) failed = e.what();
    }
    // One conversion for Close and `strut recover`: what the journal holds is what the file gets.
    JournalReport report;
    try {
      report = RecoverJournal(journal_path, session_path, true, options.write);
    } catch (const SessionError& e) {
      throw RecorderError(fmt::format("{}{}cannot write the session: {} (the journal {} is kept)", failed,
                                      failed.empty() ? "" : "; ", e.what(), journal_path));
    }
    if (!failed.empty()) {
      throw RecorderError(fmt::format("{}; {} holds what was recorded until then ({} samples), the journal {} is kept",
                                      failed, session_path, report.samples, journal_path));
    }
    if (keep_journal) return;
    std::error_code error;
    if (!std::filesystem::remove(journal_path, error)) {
      spdlog::warn("{}: written, but removing the journal {} failed: {}", session_path, journal_path, error.message());
    }
  }
};

Recorder::Recorder(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Recorder::Recorder(Recorder&&) noexcept = default;
Recorder& Recorder::operator=(Recorder&& other) noexcept {
  if (this != &other) {
    if (impl_ && !impl_->closed) {
      try {
        impl_->Close(false);
      } catch (const RecorderError& e) {  // Close's one error type; an assignment cannot throw it on
        spdlog::error("{}", e.what());
      }
    }
    impl_ = std::move(other.impl_);
  }
  return *this;
}

Recorder::~Recorder() {
  if (!impl_ || impl_->closed) return;
  try {
    impl_->Close(false);
  } catch (const RecorderError& e) {  // Close's one error type; a destructor cannot throw it on
    spdlog::error("{}", e.what());
  }
}

Recorder Recorder::Open(const std::string& session_path, const RecordingMetadata& metadata,
                        const RecorderOptions& options, std::unique_ptr<JournalSink> sink) {
  std::string error;
  if (!options.IsValid(&error)) throw RecorderError(fmt::format("{}: recorder options: {}", session_path, error));
  if (metadata.damper_serial.empty()) throw RecorderError(fmt::format("{}: metadata: damper_serial is empty", session_path));
  if (metadata.rig.empty()) throw RecorderError(fmt::format("{}: metadata: rig is empty", session_path));
  if (metadata.profile != kDamperProfile && metadata.profile != kGenericProfile) {
    throw RecorderError(fmt::format("{}: metadata: profile '{}' is neither \"damper\" nor \"generic\"", session_path,
                                    metadata.profile));
  }
  for (const auto& [name, value] : metadata.limits) {
    if (name.empty() || !std::isfinite(value)) {
      throw RecorderError(fmt::format("{}: metadata: limit '{}' = {} (a name and a finite SI value are required)",
                                      session_path, name, value));
    }
  }
  for (const MetadataGroup& g : metadata.groups) {
    if (!AllowedRootGroup(g.name)) {
      throw RecorderError(fmt::format("{}: metadata: root group '{}' is not allowed (reserved or not a name)",
                                      session_path, g.name));
    }
  }
  std::error_code ignored;
  if (!options.force && std::filesystem::exists(session_path, ignored)) {
    throw RecorderError(fmt::format("{}: exists; not overwritten (record with force to replace it)", session_path));
  }
  auto impl = std::make_unique<Impl>();
  impl->session_path = session_path;
  impl->journal_path = JournalPath(session_path);
  impl->metadata = metadata;
  if (impl->metadata.software_version.empty()) impl->metadata.software_version = "strut " STRUT_VERSION;
  impl->options = options;
  if (!sink && !options.force && std::filesystem::exists(impl->journal_path, ignored)) {
    throw RecorderError(fmt::format(
        "{}: the journal of an earlier recording is there: resume it, `strut recover {}` it first, or record with force",
        impl->journal_path, impl->journal_path));
  }
  impl->sink = sink ? std::move(sink) : CreateJournalFile(impl->journal_path, options.force);
  // The header and metadata are durable before the first sample is accepted.
  impl->sink->Write(journal::Header());
  impl->sink->Write(journal::Record(
      journal::RecordType::kOpen, journal::OpenPayload(impl->metadata, UtcNowIso8601(), journal::MonotonicNowNs(),
                                                       journal::UtcNowNs())));
  impl->sink->Sync();
  Impl* raw = impl.get();
  impl->writer = std::thread([raw] { raw->WriterLoop(); });
  return Recorder(std::move(impl));
}

Recorder Recorder::Resume(const std::string& session_path, const RecorderOptions& options, const std::string& text,
                          Session* so_far) {
  std::string error;
  if (!options.IsValid(&error)) throw RecorderError(fmt::format("{}: recorder options: {}", session_path, error));
  const std::string journal_path = JournalPath(session_path);
  std::error_code ignored;
  if (!std::filesystem::exists(journal_path, ignored)) {
    throw RecorderError(fmt::format("{}: no journal {} to resume from (a session closed complete has none)", session_path,
                                    journal_path));
  }
  JournalReport report;
  Session session = ReadJournal(journal_path, &report);
  auto impl = std::make_unique<Impl>();
  impl->session_path = session_path;
  impl->journal_path = journal_path;
  impl->metadata.damper_serial = session.damper_serial;
  impl->metadata.rig = session.rig;
  impl->metadata.profile = session.profile;
  impl->options = options;
  for (const Experiment& e : session.experiments) impl->labels.insert(e.label);
  impl->sink = ReopenJournalFile(journal_path, report.bytes_read);
  const std::int64_t now = journal::MonotonicNowNs();
  if (!report.in_progress.empty()) {
    impl->sink->Write(journal::Record(
        journal::RecordType::kEvent,
        journal::EventPayload(now, "recovered",
                              fmt::format("experiment '{}' was in progress when the recording was cut off: marked aborted",
                                          report.in_progress))));
    impl->sink->Write(journal::Record(journal::RecordType::kEnd, journal::EndPayload(EndStatus::kAborted, 0)));
  }
  impl->sink->Write(journal::Record(journal::RecordType::kResume,
                                    journal::ResumePayload(now, journal::UtcNowNs(), UtcNowIso8601(), text)));
  impl->sink->Sync();
  if (so_far != nullptr) *so_far = ReadJournal(journal_path);
  Impl* raw = impl.get();
  impl->writer = std::thread([raw] { raw->WriterLoop(); });
  return Recorder(std::move(impl));
}

void Recorder::AddMetadata(const MetadataGroup& group) {
  Impl& m = *impl_;
  std::lock_guard call(m.api);
  std::unique_lock lock(m.mutex);
  m.CheckUsable();
  if (!AllowedRootGroup(group.name)) {
    m.Throw(fmt::format("metadata group '{}' is not allowed (reserved or not a name)", group.name));
  }
  m.Enqueue(lock, journal::Record(journal::RecordType::kGroup, journal::GroupPayload(group)));
}

void Recorder::BeginExperiment(const ExperimentDescriptor& d) {
  Impl& m = *impl_;
  std::lock_guard call(m.api);
  std::unique_lock lock(m.mutex);
  m.CheckUsable();
  if (m.open) m.Throw(fmt::format("experiment '{}' begun while '{}' is open", d.header.label, m.open->label));
  m.CheckHeader(d);
  m.Enqueue(lock, journal::Record(journal::RecordType::kBegin, journal::BeginPayload(d)));
  OpenExperiment e;
  e.label = d.header.label;
  e.kind = d.header.kind;
  e.sample_rate = d.header.sample_rate;
  e.frequency = d.header.frequency;
  e.requested_periods = d.header.periods;
  for (const Channel& c : d.header.channels) e.channels.push_back(c.name);
  e.raw = d.raw.size();
  e.sequence = d.sequence;
  e.status = d.status;
  m.open = std::move(e);
  m.labels.insert(d.header.label);
}

void Recorder::Append(const SampleBlock& block) {
  Impl& m = *impl_;
  std::lock_guard call(m.api);
  std::unique_lock lock(m.mutex);
  m.CheckUsable();
  if (!m.open) m.Throw("samples handed over with no experiment open");
  m.CheckBlock(block);
  if (block.size() == 0) return;
  m.Enqueue(lock, journal::BlockRecord(block));
  m.open->samples += block.size();
  m.open->last_ns = block.monotonic_ns.back();
  m.stats.samples += block.size();
}

void Recorder::Event(std::int64_t monotonic_ns, std::string_view kind, std::string_view text) {
  Impl& m = *impl_;
  std::lock_guard call(m.api);
  std::unique_lock lock(m.mutex);
  m.CheckUsable();
  if (kind.empty()) m.Throw("an event needs a kind (trip, abort, pause, ...)");
  m.Enqueue(lock, journal::Record(journal::RecordType::kEvent, journal::EventPayload(monotonic_ns, kind, text)));
}

void Recorder::EndExperiment(EndStatus status, std::optional<long> periods) {
  Impl& m = *impl_;
  std::lock_guard call(m.api);
  std::unique_lock lock(m.mutex);
  m.CheckUsable();
  if (!m.open) m.Throw("EndExperiment with no experiment open");
  const OpenExperiment& e = *m.open;
  long stored = 0;
  if (status != EndStatus::kAborted) {
    if (e.samples == 0) m.ThrowIn("no samples: end it as aborted");
    if (e.kind == ExperimentKind::kPeriodic) {
      stored = periods.value_or(e.requested_periods);
      if (stored < 1) m.ThrowIn(fmt::format("periods must be >= 1 to end it {}, found {}", ToString(status), stored));
      Experiment probe;
      probe.periods = stored;
      probe.sample_rate = e.sample_rate;
      probe.frequency = e.frequency;
      if (auto defect = detail::PeriodCountDefect(probe, e.samples)) {
        m.ThrowIn(fmt::format("cannot end it {}: {}", ToString(status), *defect));
      }
    }
  }
  m.Enqueue(lock, journal::Record(journal::RecordType::kEnd, journal::EndPayload(status, stored)));
  m.open.reset();
}

void Recorder::Close(bool keep_journal) { impl_->Close(keep_journal); }

RecorderStats Recorder::stats() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->stats;
}

const std::string& Recorder::session_path() const { return impl_->session_path; }
const std::string& Recorder::journal_path() const { return impl_->journal_path; }

ExperimentDescriptor AcquiredExperiment(Experiment header, const StreamDescription& stream,
                                        std::string_view pressure_reference) {
  ExperimentDescriptor d;
  if (header.sample_rate == 0.0) header.sample_rate = stream.sample_rate;
  header.channels.clear();
  for (const ChannelDescriptor& c : stream.channels) {
    header.channels.push_back(
        {c.name, c.unit, c.name == "pressure" ? std::string(pressure_reference) : std::string(), {}});
    d.raw.push_back({c.name, c.calibration});
  }
  d.header = std::move(header);
  d.sequence = true;
  d.status = true;
  return d;
}

void ToRecordedTime(std::span<std::int64_t> times_ns, std::int64_t origin_ns, double speed) {
  if (speed == 1.0) return;
  for (std::int64_t& t : times_ns)
    t = origin_ns + static_cast<std::int64_t>(std::llround(static_cast<double>(t - origin_ns) * speed));
}

void ToRecordedTime(SampleBlock& block, std::int64_t origin_ns, double speed) {
  ToRecordedTime(std::span<std::int64_t>(block.monotonic_ns), origin_ns, speed);
}

SampleBlock RecordedBlock(const AcquiredBlock& block, std::size_t begin, std::size_t end) {
  end = std::min(end, block.size());
  SampleBlock b;
  if (begin >= end) return b;
  const auto first = static_cast<std::ptrdiff_t>(begin), last = static_cast<std::ptrdiff_t>(end);
  b.monotonic_ns.assign(block.time_ns.begin() + first, block.time_ns.begin() + last);
  for (const auto& v : block.values) b.values.emplace_back(v.begin() + first, v.begin() + last);
  for (const auto& c : block.counts) b.counts.emplace_back(c.begin() + first, c.begin() + last);
  for (std::size_t i = begin; i < end; ++i) b.sequence.push_back(block.first_index + i);
  b.status.assign(end - begin, block.quality.flags);
  return b;
}

}  // namespace strut::daq
