// A recorded session on the monitor as a replay plays it (monitor/replay_view.h, docs/monitor.md
// "Replay"): the session's events go out where the replayed stream reaches the point the recorder
// logged them, the matrix is the session's experiments, the limits and margins are those it
// recorded, and the progress carries the steady-state detector's cycles, checked against the
// session strut's recorder wrote (its event log read back from the file).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "recorder_fixtures.h"
#include "session_events.h"
#include "strut/daq/replay.h"
#include "strut/monitor/replay_view.h"
#include "test_support.h"

namespace strut::monitor {
namespace {

// Takes what the monitor's observer handed over after each of its calls, as the hub would if it
// took at once: which events went out with which block.
class TakeAfterEachCall : public daq::ReplayObserver {
 public:
  struct Taken {
    std::size_t experiment;
    double block_end = -1.0;  //!< s on the experiment's time axis of the block's last set (-1: not a block)
    FeedBatch batch;
  };
  explicit TakeAfterEachCall(ReplayMonitor& view, const daq::ReplayAcquisition& replay) : view_(view), replay_(replay) {}
  void BeginExperiment(const daq::ReplayedExperiment& x) override {
    view_.BeginExperiment(x);
    first_ns_ = -1;
    Take(x, -1.0);
  }
  void Block(const daq::ReplayedExperiment& x, const daq::AcquiredBlock& b) override {
    view_.Block(x, b);
    if (b.empty()) return;
    if (first_ns_ < 0) first_ns_ = b.time_ns.front();
    Take(x, static_cast<double>(b.time_ns.back() - first_ns_) * 1e-9);
  }
  void EndExperiment(const daq::ReplayedExperiment& x) override {
    view_.EndExperiment(x);
    Take(x, -1.0);
  }
  std::vector<Taken> taken;

 private:
  void Take(const daq::ReplayedExperiment& x, double end) {
    taken.push_back({static_cast<std::size_t>(&x - replay_.experiments().data()), end, view_.feed().Take()});
  }
  ReplayMonitor& view_;
  const daq::ReplayAcquisition& replay_;
  std::int64_t first_ns_ = -1;
};

TEST(MonitorReplay, RecordedEventsGoOutWhereTheReplayedStreamReachesTheirRecordedTime) {
  test::TempDir dir;
  const std::string path = dir.file("run.h5");
  test::RecordRunWithEvents(path, 3, 0.8);
  daq::ReplayOptions options;
  options.speed = 1000.0;  // 3 s recorded in 3 ms: paced, as the monitor needs
  auto replay = daq::ReplayAcquisition::Open(path, options);

  // Where each event goes: read off the recorder's own log in the file.
  const std::vector<ReplayedEvent> placed = PlaceRecordedEvents(*replay);
  const auto logged = test::SessionEvents(replay->session());
  ASSERT_EQ(placed.size(), logged.size());
  for (std::size_t i = 0; i < placed.size(); ++i) {
    EXPECT_EQ(placed[i].kind, logged[i].first);
    EXPECT_EQ(placed[i].text, logged[i].second);
  }
  const double inf = std::numeric_limits<double>::infinity();
  ASSERT_EQ(placed.size(), 4u);
  EXPECT_EQ(placed[0].experiment, 0u);  // the note before a: when a begins
  EXPECT_EQ(placed[0].time, -inf);
  EXPECT_EQ(placed[1].experiment, 0u);  // the mark in a at 0.3 s
  EXPECT_NEAR(placed[1].time, 0.3, 1e-9);
  EXPECT_EQ(placed[2].experiment, 1u);  // the trip in b at 0.8 s
  EXPECT_NEAR(placed[2].time, 0.8, 1e-9);
  EXPECT_EQ(placed[3].experiment, 2u);  // the pause after b: after the last experiment
  EXPECT_EQ(placed[3].time, -inf);

  rig::SteadyStateOnReplay steady;
  ReplayMonitor view(*replay, &steady);
  TakeAfterEachCall taker(view, *replay);
  daq::PlayReplay(*replay, nullptr, &taker);
  view.Finish();
  const FeedBatch last = view.feed().Take();

  // Each event in the first batch whose stream passed its time, not before.
  std::map<std::string, const TakeAfterEachCall::Taken*> went_out;
  std::size_t points = 0;
  for (const auto& t : taker.taken) {
    points += t.batch.t.size();
    for (const MonitorEvent& e : t.batch.events) went_out[e.kind] = &t;
  }
  ASSERT_EQ(went_out.count("note"), 1u);
  EXPECT_EQ(went_out["note"]->experiment, 0u);
  EXPECT_EQ(went_out["note"]->block_end, -1.0);  // with a's beginning, before its samples
  ASSERT_EQ(went_out.count("mark"), 1u);
  EXPECT_EQ(went_out["mark"]->experiment, 0u);
  EXPECT_GE(went_out["mark"]->block_end, 0.3);
  EXPECT_LT(went_out["mark"]->block_end, 0.3 + 50 * 0.005);  // within the block that reached it
  ASSERT_EQ(went_out.count("trip"), 1u);
  EXPECT_EQ(went_out["trip"]->experiment, 1u);
  EXPECT_GE(went_out["trip"]->block_end, 0.8);
  EXPECT_LT(went_out["trip"]->block_end, 0.8 + 50 * 0.005);
  EXPECT_EQ(went_out.count("paused"), 0u);  // after the last experiment: with Finish
  ASSERT_EQ(last.events.size(), 1u);
  EXPECT_EQ(last.events[0].kind, "paused");
  // 200 Hz at 1000x is 200,000 sets a wall second, of which the feed keeps 2000: every 100th.
  EXPECT_EQ(view.feed().stride(), 100);
  EXPECT_EQ(points, 6u);

  // The progress: the experiment, its periods and cycles played, the margins to the recorded
  // limits (100 % mid-band, 0 at a limit) over what was played, worst of the progresses sent.
  const daq::Session& s = replay->session();
  for (std::size_t k = 0; k < 2; ++k) {
    SCOPED_TRACE(s.experiments[k].label);
    rig::Margins worst;
    std::optional<rig::Progress> end;
    for (const auto& t : taker.taken) {
      if (!t.batch.progress || t.batch.progress->index != k) continue;
      const rig::Progress& p = *t.batch.progress;
      worst.stroke = std::min(worst.stroke, p.margins.stroke);
      worst.force = std::min(worst.force, p.margins.force);
      worst.pressure = std::min(worst.pressure, p.margins.pressure);
      end = p;
    }
    ASSERT_TRUE(end);
    EXPECT_EQ(end->experiment, s.experiments[k].label);
    EXPECT_EQ(end->total, 2u);
    EXPECT_EQ(end->phase, rig::RunPhase::kRecording);
    EXPECT_EQ(end->periods_recorded, 3);
    EXPECT_EQ(end->periods_requested, 3);
    EXPECT_EQ(end->cycles, 3);  // 300 samples of 100 a cycle
    const auto margin = [&](const char* channel, double lo, double hi) {
      double m = 1.0;
      for (double v : s.experiments[k].channel(channel).samples) m = std::min(m, std::min(v - lo, hi - v) / (0.5 * (hi - lo)));
      return m;
    };
    EXPECT_NEAR(worst.stroke, margin("stroke", -0.008, 0.27), 1e-12);
    EXPECT_NEAR(worst.force, margin("force", -1000.0, 1000.0), 1e-12);
    EXPECT_NEAR(worst.pressure, margin("pressure", -1e5, 18e6), 1e-12);
    EXPECT_EQ(worst.following, 1.0);  // a replay has no controller
  }
  ASSERT_TRUE(last.progress);
  EXPECT_EQ(last.progress->phase, rig::RunPhase::kDone);

  // The page's matrix: the session's experiments; its traces' limits: the recorded ones.
  const MonitorSetup setup = ReplaySetup(*replay, "replay");
  ASSERT_EQ(setup.items.size(), 2u);
  EXPECT_EQ(setup.items[1].label(), "b");
  EXPECT_EQ(setup.items[1].entry.frequency, 2.0);
  EXPECT_EQ(setup.items[1].entry.amplitude, 0.01);
  EXPECT_EQ(setup.items[1].entry.static_position, 0.1);
  EXPECT_TRUE(setup.limits.force.enabled);
  EXPECT_EQ(setup.limits.force.upper, 1000.0);
  EXPECT_EQ(setup.limits.stroke.lower, -0.008);
}

TEST(MonitorReplay, ASessionWithoutLimitsOrEventsHasNeitherAndAReplayWithoutAPaceIsRefused) {
  test::TempDir dir;
  const std::string path = dir.file("bare.h5");
  {
    daq::RecordingMetadata m = test::Metadata();
    m.limits = {{"stroke_max", 0.25}};  // one side only: no limit to draw
    daq::Recorder r = daq::Recorder::Open(path, m);
    r.BeginExperiment(test::Periodic("a", 1));
    r.Append(test::Block(0, 0, 100));
    r.EndExperiment(daq::EndStatus::kComplete);
    r.Close();
  }
  daq::ReplayOptions options;
  options.speed = 1000.0;
  auto replay = daq::ReplayAcquisition::Open(path, options);
  EXPECT_TRUE(PlaceRecordedEvents(*replay).empty());
  const MonitorSetup setup = ReplaySetup(*replay, "replay");
  EXPECT_FALSE(setup.limits.stroke.enabled);
  EXPECT_FALSE(setup.limits.force.enabled);
  ReplayMonitor view(*replay, nullptr);
  daq::PlayReplay(*replay, nullptr, &view);
  view.Finish();
  const FeedBatch all = view.feed().Take();
  ASSERT_TRUE(all.progress);
  EXPECT_EQ(all.progress->margins.stroke, 1.0);  // no limit, no margin

  auto unpaced = daq::ReplayAcquisition::Open(path, daq::ReplayOptions{});
  const std::string error = test::ErrorOf<std::invalid_argument>([&] { ReplayMonitor unpaced_view(*unpaced, nullptr); });
  EXPECT_NE(error.find("--speed"), std::string::npos) << error;
}

}  // namespace
}  // namespace strut::monitor
