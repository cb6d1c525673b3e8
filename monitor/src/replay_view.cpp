#include "strut/monitor/replay_view.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "strut/rig/campaign.h"

namespace strut::monitor {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// As the runner sends its progress: at every phase change and at most this often (wall s).
constexpr double kProgressEvery = 0.1;

std::vector<std::string> StreamChannels(const daq::ReplayAcquisition& replay) {
  std::vector<std::string> names;
  if (!replay.experiments().empty())
    for (const daq::ChannelDescriptor& c : replay.experiments().front().stream.channels) names.push_back(c.name);
  return names;
}

// Sample sets per wall second of the fastest experiment at the replay's pace: the feed keeps
// every k-th so that no experiment hands over more than its points a second.
double WallRate(const daq::ReplayAcquisition& replay) {
  const double speed = replay.options().speed;
  if (!(speed > 0.0))
    throw std::invalid_argument("the monitor shows a replay at a pace: give --speed a number (1: the recorded pace), "
                                "not max");
  double rate = 0.0;
  for (const daq::ReplayedExperiment& x : replay.experiments()) rate = std::max(rate, x.stream.sample_rate);
  return rate * speed;
}

bool Before(std::size_t ka, double ta, std::size_t kb, double tb) { return ka < kb || (ka == kb && ta < tb); }

}  // namespace

MonitorSetup ReplaySetup(const daq::ReplayAcquisition& replay, std::string title) {
  MonitorSetup setup;
  setup.title = std::move(title);
  for (const daq::ReplayedExperiment& x : replay.experiments()) {
    rig::RunItem item;
    item.entry.label = x.header.label;
    item.entry.group = x.header.group;
    item.entry.frequency = x.header.frequency;
    item.entry.static_position = x.header.static_position;
    item.entry.amplitude = x.header.amplitude;
    setup.items.push_back(std::move(item));
  }
  setup.limits = rig::RecordedLimits(replay.session());
  return setup;
}

std::vector<ReplayedEvent> PlaceRecordedEvents(const daq::ReplayAcquisition& replay) {
  std::vector<ReplayedEvent> placed;
  const daq::Session& session = replay.session();
  const daq::MetadataGroup* recording = session.find_metadata("recording");
  const daq::MetadataGroup* log = recording ? recording->find_group("events") : nullptr;
  if (log == nullptr) return placed;
  const std::size_t n = replay.experiments().size();
  // Each experiment's first sample on the recorded monotonic clock, where the recorder kept it.
  std::vector<std::optional<std::int64_t>> start(n);
  for (std::size_t k = 0; k < n && k < session.experiments.size(); ++k) {
    const auto& attributes = session.experiments[k].extra_attributes;
    if (const auto it = attributes.find("monotonic_start_ns"); it != attributes.end()) {
      try {
        start[k] = std::stoll(it->second);
      } catch (const std::exception&) {
        // not a clock this placement can use: the event goes where the one before it went
      }
    }
  }
  std::size_t at = 0;
  double time = -kInf;
  for (const daq::MetadataGroup& e : log->groups) {
    std::size_t k = at;
    double t = time;
    const std::optional<std::string> label = e.text("experiment");
    const auto during = label ? std::find_if(replay.experiments().begin(), replay.experiments().end(),
                                             [&](const daq::ReplayedExperiment& x) { return x.header.label == *label; })
                              : replay.experiments().end();
    if (during != replay.experiments().end()) {
      k = static_cast<std::size_t>(during - replay.experiments().begin());
      t = e.number("time").value_or(-kInf);
    } else if (const std::optional<double> m = e.number("monotonic_ns")) {
      // Between experiments: when the next one to begin after it begins.
      k = at;
      while (k < n && !(start[k] && static_cast<double>(*start[k]) > *m)) ++k;
      t = -kInf;
    }
    if (Before(k, t, at, time)) {  // never before the event recorded before it
      k = at;
      t = time;
    }
    at = k;
    time = t;
    placed.push_back({k, t, e.text("kind").value_or("event"), e.text("text").value_or("")});
  }
  return placed;
}

ReplayMonitor::ReplayMonitor(const daq::ReplayAcquisition& replay, rig::SteadyStateOnReplay* steady)
    : replay_(replay),
      steady_(steady),
      feed_(StreamChannels(replay), WallRate(replay), 1.0),  // the replay's timestamps are the recorded clock
      limits_(rig::RecordedLimits(replay.session())),
      events_(PlaceRecordedEvents(replay)) {}

std::size_t ReplayMonitor::IndexOf(const daq::ReplayedExperiment& x) const {
  return static_cast<std::size_t>(&x - replay_.experiments().data());
}

void ReplayMonitor::EventsUpTo(std::size_t experiment, double time) {
  for (; next_event_ < events_.size(); ++next_event_) {
    const ReplayedEvent& e = events_[next_event_];
    if (Before(experiment, time, e.experiment, e.time)) break;
    feed_.Event(e.kind, e.text);
  }
}

void ReplayMonitor::SendProgress(rig::RunPhase phase) {
  const std::vector<daq::ReplayedExperiment>& xs = replay_.experiments();
  if (xs.empty()) return;
  rig::Progress p;
  p.total = xs.size();
  p.index = std::min(index_, xs.size() - 1);
  p.experiment = xs[p.index].header.label;
  p.phase = phase;
  p.periods_requested = xs[p.index].header.periods;
  p.periods_recorded = samples_per_period_ ? static_cast<long>(played_) / *samples_per_period_ : 0;
  p.steady_measure = kInf;
  if (steady_ != nullptr) {
    p.cycles = steady_->cycles();
    if (const rig::SteadyStateVerdict* v = steady_->live()) {
      p.steady = *v;
      p.steady_measure = v->measure;
    }
  }
  if (margins_) p.margins = margins_->TakeMargins();
  p.stroke = stroke_;
  p.force = force_;
  feed_.Progress(p);
  last_progress_ = feed_.Elapsed();
}

void ReplayMonitor::BeginExperiment(const daq::ReplayedExperiment& x) {
  if (steady_ != nullptr) steady_->BeginExperiment(x);
  index_ = IndexOf(x);
  played_ = 0;
  first_ns_ = -1;
  samples_per_period_ = x.header.kind == daq::ExperimentKind::kPeriodic
                            ? daq::WholeSamplesPerPeriod(x.stream.sample_rate, x.header.frequency, 1)
                            : std::nullopt;
  std::vector<std::string> names;
  for (const daq::ChannelDescriptor& c : x.stream.channels) names.push_back(c.name);
  margins_.emplace(limits_, names);
  order_.assign(feed_.channels().size(), -1);
  for (std::size_t c = 0; c < order_.size(); ++c) {
    const auto it = std::find(names.begin(), names.end(), feed_.channels()[c]);
    if (it != names.end()) order_[c] = static_cast<int>(it - names.begin());
  }
  same_order_ = names == feed_.channels();
  const auto place = [&names](const char* name) {
    const auto it = std::find(names.begin(), names.end(), name);
    return it == names.end() ? -1 : static_cast<int>(it - names.begin());
  };
  stroke_channel_ = place("stroke");
  force_channel_ = place("force");
  EventsUpTo(index_, -kInf);
  SendProgress(rig::RunPhase::kRecording);
}

void ReplayMonitor::Block(const daq::ReplayedExperiment& x, const daq::AcquiredBlock& b) {
  if (steady_ != nullptr) steady_->Block(x, b);
  if (b.empty()) return;
  if (first_ns_ < 0) first_ns_ = b.time_ns.front();
  if (same_order_) {
    feed_.Block(b);
  } else {  // an experiment with other channels than the first: the feed's order, NaN where missing
    daq::AcquiredBlock mapped;
    mapped.time_ns = b.time_ns;
    for (const int k : order_)
      mapped.values.push_back(k >= 0 ? b.values[k] : std::vector<double>(b.size(), std::nan("")));
    feed_.Block(mapped);
  }
  margins_->CheckBlock(b);  // margins only: the trips the session had are in its events
  played_ += b.size();
  if (stroke_channel_ >= 0) stroke_ = b.values[stroke_channel_].back();
  if (force_channel_ >= 0) force_ = b.values[force_channel_].back();
  EventsUpTo(index_, static_cast<double>(b.time_ns.back() - first_ns_) * 1e-9);
  if (feed_.Elapsed() - last_progress_ >= kProgressEvery) SendProgress(rig::RunPhase::kRecording);
}

void ReplayMonitor::EndExperiment(const daq::ReplayedExperiment& x) {
  if (steady_ != nullptr) steady_->EndExperiment(x);
  SendProgress(rig::RunPhase::kRecording);
  EventsUpTo(IndexOf(x), kInf);
}

void ReplayMonitor::Finish() {
  index_ = replay_.experiments().size();
  EventsUpTo(index_, kInf);
  SendProgress(rig::RunPhase::kDone);
  feed_.Flush();
}

}  // namespace strut::monitor
