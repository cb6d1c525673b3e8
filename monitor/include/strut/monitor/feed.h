// The handoff from the acquisition thread to the live monitor (docs/monitor.md). The producer (the
// runner's thread, or a replay's) hands over decimated copies of the blocks, the progress and the
// events; it never waits: what it cannot hand over at once (the consumer holds the lock) stays in
// its own pending batch for the next call, and beyond a bound the oldest points are dropped and
// counted. The consumer (the monitor's hub thread) takes everything handed over so far.
#pragma once

#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "strut/daq/acquisition.h"
#include "strut/rig/matrix_runner.h"

namespace strut::monitor {

struct MonitorEvent {
  double wall = 0.0;  //!< wall s since the feed was made
  std::string kind, text;
};

//! What the producer handed over since the last Take.
struct FeedBatch {
  std::vector<double> t;                    //!< recorded s since the first sample
  std::vector<std::vector<double>> values;  //!< per channel, as t
  std::optional<rig::Progress> progress;    //!< the latest
  std::vector<MonitorEvent> events;
  std::uint64_t dropped = 0;                //!< points dropped because the consumer fell behind
  bool empty() const { return t.empty() && !progress && events.empty() && dropped == 0; }
};

class MonitorFeed {
 public:
  //! `channels` names the blocks' channels in order; `stream_rate` is sample sets per wall second,
  //! `speed` recorded seconds per second of the stream's clock (1 for a real rig); at most
  //! `points_per_second` samples per wall second are handed over (every k-th).
  MonitorFeed(std::vector<std::string> channels, double stream_rate, double speed, double points_per_second = 2000.0);

  const std::vector<std::string>& channels() const { return channels_; }
  double speed() const { return speed_; }
  int stride() const { return stride_; }
  //! Wall s since the feed was made (the clock of MonitorEvent::wall).
  double Elapsed() const;

  // ---- the producer: one thread; none of these waits
  void Block(const daq::AcquiredBlock& block);
  void Progress(const rig::Progress& progress);
  void Event(std::string_view kind, const std::string& text);
  //! The producer's last call: waits for the consumer and hands over everything still pending,
  //! so the run's last event (a pause, an abort) reaches the page.
  void Flush();

  // ---- the consumer
  FeedBatch Take();

 private:
  void Offer();
  static void Append(FeedBatch& to, FeedBatch& from);

  std::vector<std::string> channels_;
  double speed_;
  int stride_;
  std::int64_t created_ns_;
  // Producer-only.
  FeedBatch pending_;
  std::uint64_t count_ = 0;
  std::optional<std::int64_t> origin_ns_;
  // Shared, under mutex_ (the producer only try-locks it).
  std::mutex mutex_;
  FeedBatch shared_;
};

}  // namespace strut::monitor
