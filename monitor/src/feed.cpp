#include "strut/monitor/feed.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace strut::monitor {

namespace {
// Points kept for a consumer that does not take them: a minute of the default rate.
constexpr std::size_t kMaxPendingPoints = 120000;
}  // namespace

MonitorFeed::MonitorFeed(std::vector<std::string> channels, double stream_rate, double speed, double points_per_second)
    : channels_(std::move(channels)), speed_(speed), created_ns_(daq::MonotonicNs()) {
  if (!(stream_rate > 0 && speed > 0 && points_per_second > 0))
    throw std::invalid_argument(fmt::format("monitor feed: rate {} Hz, speed {} and {} points a second must be positive",
                                            stream_rate, speed, points_per_second));
  stride_ = std::max(1, static_cast<int>(std::ceil(stream_rate / points_per_second)));
  pending_.values.resize(channels_.size());
  shared_.values.resize(channels_.size());
}

void MonitorFeed::Block(const daq::AcquiredBlock& block) {
  if (!block.empty()) {
    if (!origin_ns_) origin_ns_ = block.time_ns.front();
    for (std::size_t i = 0; i < block.size(); ++i, ++count_) {
      if (count_ % static_cast<std::uint64_t>(stride_) != 0) continue;
      pending_.t.push_back(static_cast<double>(block.time_ns[i] - *origin_ns_) * 1e-9 * speed_);
      for (std::size_t c = 0; c < channels_.size(); ++c)
        pending_.values[c].push_back(c < block.values.size() ? block.values[c][i] : NAN);
    }
    if (pending_.t.size() > kMaxPendingPoints) {
      const std::size_t drop = pending_.t.size() - kMaxPendingPoints;
      pending_.t.erase(pending_.t.begin(), pending_.t.begin() + static_cast<std::ptrdiff_t>(drop));
      for (auto& v : pending_.values) v.erase(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(drop));
      pending_.dropped += drop;
    }
  }
  Offer();
}

void MonitorFeed::Progress(const rig::Progress& progress) {
  pending_.progress = progress;
  Offer();
}

double MonitorFeed::Elapsed() const { return static_cast<double>(daq::MonotonicNs() - created_ns_) * 1e-9; }

void MonitorFeed::Event(std::string_view kind, const std::string& text) {
  pending_.events.push_back({Elapsed(), std::string(kind), text});
  Offer();
}

void MonitorFeed::Append(FeedBatch& to, FeedBatch& from) {
  to.t.insert(to.t.end(), from.t.begin(), from.t.end());
  for (std::size_t c = 0; c < to.values.size(); ++c)
    to.values[c].insert(to.values[c].end(), from.values[c].begin(), from.values[c].end());
  if (from.progress) to.progress = std::move(from.progress);
  for (MonitorEvent& e : from.events) to.events.push_back(std::move(e));
  to.dropped += from.dropped;
  from.t.clear();
  for (auto& v : from.values) v.clear();
  from.progress.reset();
  from.events.clear();
  from.dropped = 0;
}

void MonitorFeed::Offer() {
  std::unique_lock lock(mutex_, std::try_to_lock);
  if (!lock.owns_lock()) return;  // the consumer is taking: hand over at the next call
  Append(shared_, pending_);
}

void MonitorFeed::Flush() {
  std::lock_guard lock(mutex_);
  Append(shared_, pending_);
}

FeedBatch MonitorFeed::Take() {
  FeedBatch out;
  out.values.resize(channels_.size());
  std::lock_guard lock(mutex_);
  Append(out, shared_);
  return out;
}

}  // namespace strut::monitor
