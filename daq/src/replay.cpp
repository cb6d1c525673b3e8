// Replay of a recorded session as an acquisition stream (replay.h, docs/replay.md).
#include "strut/daq/replay.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <time.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>

namespace strut::daq {

namespace {

using namespace std::chrono_literals;

// Attributes the recorder writes itself (it refuses them in a descriptor).
constexpr const char* kRecorderAttributes[] = {"recording_end", "monotonic_start_ns", "utc_start",
                                               "requested_periods"};

void SleepUntil(std::int64_t monotonic_ns) {
  timespec t{};
  t.tv_sec = static_cast<time_t>(monotonic_ns / 1'000'000'000);
  t.tv_nsec = static_cast<long>(monotonic_ns % 1'000'000'000);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &t, nullptr) == EINTR) {
  }
}

std::string FileName(const Session& s) { return s.source_path.empty() ? std::string("session") : s.source_path; }

// A channel of whole numbers (counts, sequence, status) as integers, or SessionError naming it.
template <typename T>
std::vector<T> WholeNumbers(const Session& s, const Experiment& e, const Channel& c, double low, double high) {
  std::vector<T> out(c.samples.size());
  for (std::size_t i = 0; i < out.size(); ++i) {
    const double v = c.samples[i];
    if (!(v >= low && v <= high) || v != std::floor(v)) {
      throw SessionError(fmt::format("{}: experiment '{}': channel '{}': sample {} is {}, not a whole number in "
                                     "{:.0f}..{:.0f}: not what a recorder writes there, so it cannot be replayed",
                                     FileName(s), e.label, c.name, i, v, low, high));
    }
    out[i] = static_cast<T>(v);
  }
  return out;
}

// The calibration a recorder stored for `channel` of `label` (/recording/calibration/LABEL/CHANNEL),
// or nullptr when there is none.
const MetadataGroup* StoredCalibration(const Session& s, const std::string& label, const std::string& channel) {
  const MetadataGroup* recording = s.find_metadata("recording");
  const MetadataGroup* all = recording ? recording->find_group("calibration") : nullptr;
  const MetadataGroup* experiment = all ? all->find_group(label) : nullptr;
  return experiment ? experiment->find_group(channel) : nullptr;
}

Calibration ReadCalibration(const Session& s, const Experiment& e, const std::string& channel, const MetadataGroup& g) {
  Calibration c;
  double* fields[] = {&c.gain, &c.offset, &c.range_min, &c.range_max};
  const char* names[] = {"gain", "offset", "range_min", "range_max"};
  for (int k = 0; k < 4; ++k) {
    const std::optional<double> v = g.number(names[k]);
    if (!v) {
      throw SessionError(fmt::format("{}: /recording/calibration/{}/{}: attribute '{}' missing or not a number",
                                     FileName(s), e.label, channel, names[k]));
    }
    *fields[k] = *v;
  }
  std::string why;
  if (!c.IsValid(&why)) {
    throw SessionError(fmt::format("{}: /recording/calibration/{}/{}: {}", FileName(s), e.label, channel, why));
  }
  return c;
}

// The calibration that spans a channel's recorded values with the signed 16-bit counts.
Calibration DerivedCalibration(double low, double high) {
  if (!(low < high)) {  // a constant channel: any small span around it
    const double half = std::max(std::abs(low) * 1e-3, 1e-3);
    low -= half;
    high += half;
  }
  return Calibration::FromRange16(low, high);
}

}  // namespace

bool ReplayOptions::IsValid(std::string* error) const {
  if (!std::isfinite(speed) || speed < 0.0) {
    if (error) *error = fmt::format("speed {} is not a finite number >= 0 (0: as fast as possible)", speed);
    return false;
  }
  return true;
}

std::string ReplayOptions::pace() const {
  return speed > 0.0 ? fmt::format("at {}x", speed) : std::string("as fast as possible");
}

struct ReplayAcquisition::Track {
  std::vector<std::size_t> channel;               //!< per stream channel: index among the experiment's channels
  std::vector<std::vector<std::int32_t>> counts;  //!< per stream channel
  std::vector<std::int64_t> offset_ns;            //!< stream time of each set since Start
  std::vector<std::uint64_t> sequence;            //!< empty when the session has none
  std::vector<std::uint32_t> status;              //!< empty when the session has none
  std::size_t block_sets = 1;
  std::size_t size() const { return offset_ns.size(); }
};

// What the session says about its channels before any is played: the calibrations a recorder
// stored and the counts channels beside them, and the value range of the others (one derived
// calibration per channel name for the whole session, so that a CAN receiver can use one).
struct ReplayAcquisition::Sources {
  struct Range {
    double low = std::numeric_limits<double>::infinity(), high = -std::numeric_limits<double>::infinity();
  };
  bool by_recorder = false;  //!< the session has a /recording group: its sequence and status channels are the recorder's
  std::vector<std::map<std::string, Calibration>> stored;  //!< per experiment: channel -> its stored calibration
  std::vector<std::map<std::string, std::string>> counts_of;  //!< per experiment: channel -> its counts channel
  std::map<std::string, Range> ranges;  //!< per channel name without a stored calibration

  static Sources Of(const Session& s) {
    Sources out;
    out.by_recorder = s.find_metadata("recording") != nullptr;
    out.stored.resize(s.experiments.size());
    out.counts_of.resize(s.experiments.size());
    for (std::size_t k = 0; k < s.experiments.size(); ++k) {
      const Experiment& e = s.experiments[k];
      for (const Channel& c : e.channels) {
        const MetadataGroup* g = StoredCalibration(s, e.label, c.name);
        if (g == nullptr) continue;
        const std::string counts = g->text("counts_channel").value_or(c.name + "_counts");
        if (e.find_channel(counts) == nullptr) {
          throw SessionError(fmt::format("{}: experiment '{}': channel '{}' has a calibration but no counts channel '{}'",
                                         FileName(s), e.label, c.name, counts));
        }
        out.stored[k][c.name] = ReadCalibration(s, e, c.name, *g);
        out.counts_of[k][c.name] = counts;
      }
    }
    for (std::size_t k = 0; k < s.experiments.size(); ++k) {
      for (const Channel& c : s.experiments[k].channels) {
        if (!out.IsStreamChannel(k, c) || out.stored[k].count(c.name) != 0) continue;
        Range& r = out.ranges[c.name];
        for (double v : c.samples) r.low = std::min(r.low, v), r.high = std::max(r.high, v);
      }
    }
    return out;
  }

  //! A channel the stream carries: not a counts channel, nor the recorder's sequence or status.
  bool IsStreamChannel(std::size_t k, const Channel& c) const {
    for (const auto& [name, counts] : counts_of[k])
      if (c.name == counts) return false;
    return !(by_recorder && (c.name == "sequence" || c.name == "status") && c.units == "1");
  }
};

namespace {

// The experiment as the replay plays it, before its channels: the header without samples nor the
// recorder's own attributes, how the recording ended it, the stream's source and rate.
ReplayedExperiment ReplayHeader(const Experiment& e, const std::string& file) {
  ReplayedExperiment x;
  x.header = e;
  x.header.time.clear();
  x.header.channels.clear();
  for (const char* name : kRecorderAttributes) x.header.extra_attributes.erase(name);
  x.samples = e.sample_count();
  x.periods = e.periods;
  const auto recording_end = e.extra_attributes.find("recording_end");
  if (e.status == "aborted") {
    x.end = EndStatus::kAborted;
    x.header.periods = 0;
    if (const auto requested = e.extra_attributes.find("requested_periods"); requested != e.extra_attributes.end()) {
      try {
        x.header.periods = std::stol(requested->second);
      } catch (const std::invalid_argument&) {
        spdlog::warn("{}: experiment '{}': requested_periods '{}' is no number; replayed without it", file, e.label,
                     requested->second);
      } catch (const std::out_of_range&) {
        spdlog::warn("{}: experiment '{}': requested_periods '{}' is no number; replayed without it", file, e.label,
                     requested->second);
      }
    }
  } else {
    x.end = recording_end != e.extra_attributes.end() && recording_end->second == ToString(EndStatus::kNotSteady)
                ? EndStatus::kNotSteady
                : EndStatus::kComplete;
  }
  x.stream.source = fmt::format("replay:{}", file);
  x.stream.sample_rate = e.sample_rate;
  return x;
}

}  // namespace

ReplayAcquisition::ReplayAcquisition(Session session, ReplayOptions options)
    : session_(std::move(session)), options_(options) {
  std::string why;
  if (!options_.IsValid(&why)) throw std::invalid_argument(fmt::format("replay options: {}", why));
  if (session_.experiments.empty())
    throw SessionError(fmt::format("{}: no experiments to replay", FileName(session_)));
  const Sources sources = Sources::Of(session_);
  std::int64_t base_ns = 0;  // stream time of the experiment's first set
  for (std::size_t k = 0; k < session_.experiments.size(); ++k) AddExperiment(sources, k, base_ns);
}

void ReplayAcquisition::AddExperiment(const Sources& sources, std::size_t k, std::int64_t& base_ns) {
  const Session& s = session_;
  const std::string file = FileName(s);
  const Experiment& e = s.experiments[k];
  ReplayedExperiment x = ReplayHeader(e, file);
  Track t;
  AddStreamChannels(sources, k, x, t);
  if (x.stream.channels.empty()) {
    throw SessionError(fmt::format("{}: experiment '{}': no channel to replay", file, e.label));
  }
  if (sources.by_recorder) {
    if (const Channel* c = e.find_channel("sequence"); c != nullptr && c->units == "1") {
      t.sequence = WholeNumbers<std::uint64_t>(s, e, *c, 0.0, 9007199254740992.0);
      x.recorded_sequence = true;
    }
    if (const Channel* c = e.find_channel("status"); c != nullptr && c->units == "1") {
      t.status = WholeNumbers<std::uint32_t>(s, e, *c, 0.0, 4294967295.0);
      x.recorded_status = true;
    }
  }
  ReadTimeAxis(file, e, base_ns, x, t);
  const std::int64_t period_ns = std::llround(1e9 / e.sample_rate);
  base_ns = t.offset_ns.back() + period_ns;
  t.block_sets = options_.block_sets > 0 ? options_.block_sets
                                         : std::max<std::size_t>(1, static_cast<std::size_t>(e.sample_rate / 100));
  experiments_.push_back(std::move(x));
  tracks_.push_back(std::move(t));
}

void ReplayAcquisition::AddStreamChannels(const Sources& sources, std::size_t k, ReplayedExperiment& x,
                                          Track& t) const {
  const Session& s = session_;
  const Experiment& e = s.experiments[k];
  for (std::size_t c = 0; c < e.channels.size(); ++c) {
    const Channel& channel = e.channels[c];
    if (!sources.IsStreamChannel(k, channel)) continue;
    x.header.channels.push_back({channel.name, channel.units, channel.reference, {}});
    t.channel.push_back(c);
    if (const auto cal = sources.stored[k].find(channel.name); cal != sources.stored[k].end()) {
      x.stream.channels.push_back({channel.name, channel.units, cal->second});
      x.recorded_counts.push_back(true);
      t.counts.push_back(WholeNumbers<std::int32_t>(s, e, e.channel(sources.counts_of[k].at(channel.name)),
                                                    std::numeric_limits<std::int32_t>::min(),
                                                    std::numeric_limits<std::int32_t>::max()));
    } else {
      const Sources::Range& r = sources.ranges.at(channel.name);
      const Calibration derived = DerivedCalibration(r.low, r.high);
      x.stream.channels.push_back({channel.name, channel.units, derived});
      x.recorded_counts.push_back(false);
      std::vector<std::int32_t> counts(channel.samples.size());
      for (std::size_t i = 0; i < counts.size(); ++i) counts[i] = derived.ToCounts16(channel.samples[i]);
      t.counts.push_back(std::move(counts));
    }
  }
}

void ReplayAcquisition::ReadTimeAxis(const std::string& file, const Experiment& e, std::int64_t base_ns,
                                     ReplayedExperiment& x, Track& t) {
  // The time axis in whole ns: exact when every time is k / 1e9 (what the recorder writes).
  t.offset_ns.resize(e.time.size());
  const std::int64_t first = std::llround(e.time.front() * 1e9);
  x.exact_time = first == 0;
  for (std::size_t i = 0; i < e.time.size(); ++i) {
    const std::int64_t d = std::llround(e.time[i] * 1e9) - first;
    if (i > 0 && base_ns + d <= t.offset_ns[i - 1]) {
      throw SessionError(fmt::format("{}: experiment '{}': time step {} s at sample {} is below a nanosecond", file,
                                     e.label, e.time[i] - e.time[i - 1], i));
    }
    if (static_cast<double>(d) / 1e9 != e.time[i]) x.exact_time = false;
    t.offset_ns[i] = base_ns + d;
  }
}

ReplayAcquisition::~ReplayAcquisition() = default;

std::unique_ptr<ReplayAcquisition> ReplayAcquisition::Open(const std::string& path, ReplayOptions options) {
  return std::make_unique<ReplayAcquisition>(ReadSession(path), options);
}

const StreamDescription& ReplayAcquisition::description() const {
  return experiments_[std::min(current_, experiments_.size() - 1)].stream;
}

double ReplayAcquisition::recorded_seconds() const {
  return static_cast<double>(tracks_.back().offset_ns.back()) / 1e9 + 1.0 / experiments_.back().stream.sample_rate;
}

const std::vector<std::int32_t>& ReplayAcquisition::counts(std::size_t experiment, std::size_t channel) const {
  return tracks_.at(experiment).counts.at(channel);
}

void ReplayAcquisition::Start() {
  stats_ = {};
  current_ = 0;
  position_ = 0;
  next_index_ = 0;
  start_ns_ = MonotonicNs();
  running_ = true;
}

void ReplayAcquisition::Stop() { running_ = false; }

std::size_t ReplayAcquisition::RunLength(const Track& t, std::size_t from) const {
  const std::size_t end = std::min(t.size(), from + t.block_sets);
  std::size_t i = from + 1;
  for (; i < end; ++i) {
    if (!t.status.empty() && t.status[i] != t.status[from]) break;
    if (!t.sequence.empty() && t.sequence[i] != t.sequence[i - 1] + 1) break;
  }
  return i - from;
}

std::int64_t ReplayAcquisition::DueNs(const Track& t, std::size_t i) const {
  return start_ns_ + std::llround(static_cast<double>(t.offset_ns[i]) / options_.speed);
}

AcquiredBlock ReplayAcquisition::Read(std::chrono::nanoseconds timeout) {
  if (!running_) {
    throw DeviceError(DeviceError::Kind::kInvalidValue, description().source, "read", "", 0,
                      "Read before Start or after Stop");
  }
  AcquiredBlock block;
  if (finished()) {
    block.clock = NowTimePair();
    return block;
  }
  const Track& t = tracks_[current_];
  std::size_t n = RunLength(t, position_);
  if (options_.speed > 0.0) {
    constexpr std::int64_t kLongest = std::int64_t{3600} * 1'000'000'000;  // no overflow for huge timeouts
    const std::int64_t deadline = MonotonicNs() + std::clamp<std::int64_t>(timeout.count(), 0, kLongest);
    std::size_t due = 0;
    while (due < n && DueNs(t, position_ + due) <= deadline) ++due;
    if (due == 0) {
      SleepUntil(deadline);
      block.clock = NowTimePair();
      return block;
    }
    n = due;
    SleepUntil(DueNs(t, position_ + n - 1));
  }
  const Experiment& e = session_.experiments[current_];
  const auto from = static_cast<std::ptrdiff_t>(position_), to = static_cast<std::ptrdiff_t>(position_ + n);
  block.first_index = t.sequence.empty() ? next_index_ : t.sequence[position_];
  next_index_ = block.first_index + n;
  block.quality.flags = t.status.empty() ? 0u : t.status[position_];
  block.time_ns.resize(n);
  for (std::size_t i = 0; i < n; ++i) block.time_ns[i] = start_ns_ + t.offset_ns[position_ + i];
  for (std::size_t c = 0; c < t.channel.size(); ++c) {
    const std::vector<double>& v = e.channels[t.channel[c]].samples;
    block.values.emplace_back(v.begin() + from, v.begin() + to);
    block.counts.emplace_back(t.counts[c].begin() + from, t.counts[c].begin() + to);
  }
  block.last_frame_ns = MonotonicNs();
  block.clock = NowTimePair();
  stats_.sample_sets += n;
  if (!block.quality.valid()) stats_.invalid_sample_sets += n;
  position_ += n;
  if (position_ == t.size()) {
    ++current_;
    position_ = 0;
  }
  return block;
}

ExperimentDescriptor RecordingDescriptor(const ReplayedExperiment& x) {
  const Channel* pressure = x.header.find_channel("pressure");
  ExperimentDescriptor d =
      AcquiredExperiment(x.header, x.stream, pressure && !pressure->reference.empty() ? pressure->reference : "gauge");
  std::vector<RawChannel> raw;
  for (std::size_t c = 0; c < d.raw.size(); ++c)
    if (x.recorded_counts[c]) raw.push_back(std::move(d.raw[c]));
  d.raw = std::move(raw);
  d.sequence = x.recorded_sequence;
  d.status = x.recorded_status;
  return d;
}

SampleBlock RecordingBlock(const ReplayedExperiment& x, const AcquiredBlock& block) {
  // RecordedBlock's rules (one place for them), then what the recording does not keep dropped: the
  // derived counts' copies cost less than a second set of rules that could drift from the recorder's.
  SampleBlock b = RecordedBlock(block);
  std::vector<std::vector<std::int32_t>> counts;
  for (std::size_t c = 0; c < b.counts.size(); ++c)
    if (x.recorded_counts[c]) counts.push_back(std::move(b.counts[c]));
  b.counts = std::move(counts);
  if (!x.recorded_sequence) b.sequence.clear();
  if (!x.recorded_status) b.status.clear();
  return b;
}

RecordingMetadata ReplayMetadata(const Session& s) {
  RecordingMetadata m;
  m.damper_serial = s.damper_serial;
  m.rig = s.rig;
  m.profile = s.profile;
  for (const MetadataGroup& g : s.metadata) {
    if (g.name != "recording") m.groups.push_back(g);
  }
  if (const MetadataGroup* r = s.find_metadata("recording")) {
    m.operator_name = r->text("operator").value_or("");
    m.matrix = r->text("matrix").value_or("");
    if (const MetadataGroup* limits = r->find_group("limits")) {
      for (const auto& [name, value] : limits->attributes)
        if (const auto number = limits->number(name)) m.limits[name] = *number;
    }
  }
  return m;
}

namespace {

// The loop both plays share: experiment by experiment, every block to `on_block`.
template <typename Begin, typename OnBlock, typename End>
ReplayFigures Play(ReplayAcquisition& replay, ReplayObserver* observer, Begin begin, OnBlock on_block, End end) {
  const std::int64_t started = MonotonicNs();
  ReplayFigures f;
  replay.Start();
  while (!replay.finished()) {
    const std::size_t k = replay.next_experiment();
    const ReplayedExperiment& x = replay.experiments()[k];
    begin(x);
    if (observer) observer->BeginExperiment(x);
    while (!replay.finished() && replay.next_experiment() == k) {
      const AcquiredBlock b = replay.Read(100ms);
      if (b.empty()) continue;
      if (observer) observer->Block(x, b);
      on_block(x, b);
      f.sample_sets += b.size();
    }
    end(x);
    if (observer) observer->EndExperiment(x);
    ++f.experiments;
  }
  replay.Stop();
  f.recorded_s = replay.recorded_seconds();
  f.wall_s = static_cast<double>(MonotonicNs() - started) / 1e9;
  return f;
}

}  // namespace

ReplayFigures PlayReplay(ReplayAcquisition& replay, Recorder* recorder, ReplayObserver* observer) {
  if (recorder) {
    recorder->Event(MonotonicNs(), "replay",
                    fmt::format("replay of {} {}", FileName(replay.session()), replay.options().pace()));
  }
  return Play(
      replay, observer,
      [&](const ReplayedExperiment& x) {
        if (recorder) recorder->BeginExperiment(RecordingDescriptor(x));
      },
      [&](const ReplayedExperiment& x, const AcquiredBlock& b) {
        if (recorder) recorder->Append(RecordingBlock(x, b));
      },
      [&](const ReplayedExperiment& x) {
        if (!recorder) return;
        if (x.end == EndStatus::kAborted) {
          recorder->EndExperiment(EndStatus::kAborted);
        } else {
          recorder->EndExperiment(x.end, x.periods);
        }
      });
}

CanAcquisitionOptions ReplayCanOptions(const ReplayAcquisition& replay, std::uint8_t module) {
  const std::string file = FileName(replay.session());
  const auto& xs = replay.experiments();
  const StreamDescription& first = xs.front().stream;
  for (const ReplayedExperiment& x : xs) {
    const std::string where = fmt::format("{}: experiment '{}'", file, x.header.label);
    if (x.stream.sample_rate != first.sample_rate) {
      throw SessionError(fmt::format("{}: sampled at {} Hz, experiment '{}' at {} Hz: a CAN stream has one rate",
                                     where, x.stream.sample_rate, xs.front().header.label, first.sample_rate));
    }
    if (x.stream.channels.size() != first.channels.size()) {
      throw SessionError(fmt::format("{}: {} channels, experiment '{}' {}: a CAN stream has one set of channels", where,
                                     x.stream.channels.size(), xs.front().header.label, first.channels.size()));
    }
    for (std::size_t c = 0; c < first.channels.size(); ++c) {
      const ChannelDescriptor &a = x.stream.channels[c], &b = first.channels[c];
      const Calibration &ca = a.calibration, &cb = b.calibration;
      if (a.name != b.name || a.unit != b.unit) {
        throw SessionError(fmt::format("{}: channel {} is '{}' [{}], in experiment '{}' '{}' [{}]", where, c, a.name,
                                       a.unit, xs.front().header.label, b.name, b.unit));
      }
      if (ca.gain != cb.gain || ca.offset != cb.offset) {
        throw SessionError(fmt::format("{}: channel '{}': calibration {} + {} x counts differs from experiment '{}' "
                                       "({} + {} x counts): a CAN receiver has one",
                                       where, a.name, ca.offset, ca.gain, xs.front().header.label, cb.offset, cb.gain));
      }
    }
  }
  // Derived counts are 16-bit by construction (ToCounts16); recorded ones may have been wider.
  for (std::size_t k = 0; k < xs.size(); ++k) {
    for (std::size_t c = 0; c < first.channels.size(); ++c) {
      if (!xs[k].recorded_counts[c]) continue;
      const std::vector<std::int32_t>& counts = replay.counts(k, c);
      const auto bad = std::find_if(counts.begin(), counts.end(), [](std::int32_t v) {
        return v < std::numeric_limits<std::int16_t>::min() || v > std::numeric_limits<std::int16_t>::max();
      });
      if (bad != counts.end()) {
        throw SessionError(fmt::format("{}: experiment '{}': channel '{}': count {} at sample {} does not fit the 16 "
                                       "bits of a CAN sample frame",
                                       file, xs[k].header.label, first.channels[c].name, *bad, bad - counts.begin()));
      }
    }
  }
  CanAcquisitionOptions o;
  // The wire carries the recorded rate times the pace, and a receiver checks frames against a
  // clock at the rate it is given: frames more than max(1024 sets, 0.5 s) ahead of it are taken
  // for a restarted module and dropped (docs/can-acquisition.md). So the stream's rate is the pace's.
  const double speed = replay.options().speed;
  if (!(speed > 0.0)) {
    throw std::invalid_argument(fmt::format("{}: a CAN stream needs a pace (speed > 0): a receiver checks the frames "
                                            "against its clock, as fast as possible it would drop them",
                                            file));
  }
  o.sample_rate = first.sample_rate * speed;
  o.channels = first.channels;
  o.layout.channels = static_cast<int>(first.channels.size());
  o.layout.module = module;
  const int status_every = StatusEvery(o.sample_rate);
  o.layout.fd = o.layout.channels > 4 || o.sample_rate > MaxSampleRate(o.layout, CanBitrates{}, 0.5, status_every);
  std::string why;
  if (!o.IsValid(&why)) throw SessionError(fmt::format("{}: cannot be sent over CAN: {}", file, why));
  return o;
}

ReplayFigures SendReplay(ReplayAcquisition& replay, std::unique_ptr<CanTransport> transport,
                         const CanAcquisitionOptions& options, ReplayObserver* observer) {
  const int status_every = StatusEvery(options.sample_rate);
  CanAcquisitionSender sender(std::move(transport), options.layout, status_every);
  std::vector<std::int16_t> set(options.channels.size());
  sender.SendStatus();  // the receiver's first heartbeat before the first sample
  const auto nothing = [](const ReplayedExperiment&) {};
  ReplayFigures f = Play(replay, observer, nothing,
                         [&](const ReplayedExperiment&, const AcquiredBlock& b) {
                           for (std::size_t i = 0; i < b.size(); ++i) {
                             for (std::size_t c = 0; c < set.size(); ++c)
                               set[c] = static_cast<std::int16_t>(b.counts[c][i]);
                             sender.Add(set);
                           }
                           sender.Flush();
                         },
                         nothing);
  sender.Flush();
  sender.SendStatus();
  const auto per_frame = static_cast<std::uint64_t>(options.layout.sets_per_frame());
  if (const std::uint64_t left = sender.encoder().next_index() % per_frame; left != 0) {
    spdlog::warn("{}: the last {} sample sets were not sent: a CAN FD frame carries {}", sender.transport().name(), left,
                 per_frame);
  }
  return f;
}

}  // namespace strut::daq
