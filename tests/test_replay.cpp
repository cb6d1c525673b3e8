// Replay of recorded sessions (daq/replay.h, docs/replay.md): record, replay, re-record gives the
// same samples bit for bit (SI values, counts, sequence, status, time axis) for sessions of
// strut's recorder; over UDP a CanAcquisition receives the counts; experiment boundaries, pacing
// and bad input. Sessions of `strut sim matrix` and of another tool, identification of the
// original and of the re-recording, and `strut replay` itself: test_replay_cli.cpp.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <thread>

#include "replay_fixtures.h"
#include "session_events.h"
#include "strut/daq/can_acquisition.h"
#include "strut/daq/replay.h"
#include "test_support.h"

namespace strut::daq {
namespace {

using namespace std::chrono_literals;
using test::ExpectSameDatasetsInH5py;
using test::ExpectSameSamples;
using test::Receiver;
using test::RecordedSession;
using test::SameBits;
using test::TempDir;

// Watches the stream as a steady-state detector would.
struct Watcher : ReplayObserver {
  std::vector<std::string> log;
  std::vector<std::size_t> sets;
  std::vector<std::uint64_t> indices;
  std::vector<std::uint32_t> flags;
  void BeginExperiment(const ReplayedExperiment& x) override {
    log.push_back("begin " + x.header.label);
    sets.push_back(0);
  }
  void Block(const ReplayedExperiment&, const AcquiredBlock& b) override {
    sets.back() += b.size();
    for (std::size_t i = 0; i < b.size(); ++i) {
      indices.push_back(b.first_index + i);
      flags.push_back(b.quality.flags);
    }
  }
  void EndExperiment(const ReplayedExperiment& x) override { log.push_back("end " + x.header.label); }
};

TEST(Replay, RecorderSessionReRecordsCountsSequenceStatusAndCalibrationBitForBit) {
  TempDir dir;
  const std::string original = RecordedSession(dir), again = dir.file("again.h5");
  auto replay = ReplayAcquisition::Open(original);
  ASSERT_EQ(replay->experiments().size(), 3u);
  const ReplayedExperiment& a = replay->experiments()[0];
  EXPECT_EQ(a.recorded_counts, (std::vector<bool>{true, true, false}));
  EXPECT_TRUE(a.recorded_sequence);
  EXPECT_TRUE(a.recorded_status);
  EXPECT_TRUE(a.exact_time);
  EXPECT_EQ(replay->experiments()[1].end, EndStatus::kAborted);
  EXPECT_EQ(replay->experiments()[1].header.periods, 4);  // as requested
  EXPECT_EQ(replay->experiments()[2].end, EndStatus::kNotSteady);
  Watcher watcher;
  {
    Recorder r = Recorder::Open(again, ReplayMetadata(replay->session()));
    const ReplayFigures f = PlayReplay(*replay, &r, &watcher);
    r.Close();
    EXPECT_EQ(f.sample_sets, 650u);
    EXPECT_EQ(f.experiments, 3u);
  }
  EXPECT_EQ(watcher.log, (std::vector<std::string>{"begin a", "end a", "begin b", "end b", "begin c", "end c"}));
  EXPECT_EQ(watcher.sets, (std::vector<std::size_t>{300, 150, 200}));
  const Session s = ReadSession(original), t = ReadSession(again);
  ExpectSameSamples(s, t);
  ExpectSameDatasetsInH5py(dir, original, again);
  // What the stream carried is what the session holds: indices are its sequence, qualities its status.
  std::size_t n = 0;
  for (const Experiment& e : s.experiments)
    for (std::size_t i = 0; i < e.sample_count(); ++i, ++n) {
      ASSERT_EQ(static_cast<double>(watcher.indices[n]), e.channel("sequence").samples[i]) << e.label << i;
      ASSERT_EQ(static_cast<double>(watcher.flags[n]), e.channel("status").samples[i]) << e.label << i;
    }
  // Calibration, limits, operator, matrix and the truth group go along.
  const MetadataGroup* cal = t.find_metadata("recording")->find_group("calibration");
  ASSERT_NE(cal, nullptr);
  for (const char* label : {"a", "b", "c"})
    for (const char* channel : {"stroke", "force"}) {
      const MetadataGroup* x = s.find_metadata("recording")->find_group("calibration")->find_group(label)->find_group(channel);
      const MetadataGroup* y = cal->find_group(label)->find_group(channel);
      ASSERT_NE(y, nullptr) << label << channel;
      for (const char* attribute : {"gain", "offset", "range_min", "range_max"})
        EXPECT_TRUE(SameBits(*x->number(attribute), *y->number(attribute))) << label << channel << attribute;
    }
  EXPECT_EQ(*t.find_metadata("recording")->find_group("limits")->number("force_max"), 20000.0);
  EXPECT_EQ(*t.find_metadata("recording")->text("operator"), "J. Doe");
  EXPECT_EQ(*t.find_metadata("truth")->number("theta1"), 1.5);
  EXPECT_EQ(t.experiment("a").extra_attributes.at("note"), "run a");
  std::string events;
  for (const auto& [kind, text] : test::SessionEvents(t)) events += kind + ": " + text + "\n";
  EXPECT_NE(events.find("replay: replay of " + original + " as fast as possible"), std::string::npos) << events;
}

// An in-memory session of another tool: experiments at 200 Hz and 500 Hz, no counts.
Session TwoRateSession() {
  Session s;
  s.source_path = "two-rate.h5";
  s.created_utc = "2026-01-01T00:00:00Z";
  s.damper_serial = "X";
  s.rig = "Y";
  for (const auto& [label, rate, n] : {std::tuple{"p", 200.0, 400}, std::tuple{"q", 500.0, 250}}) {
    Experiment e;
    e.label = label;
    e.sample_rate = rate;
    e.frequency = rate / 50;
    e.amplitude = 0.01;
    e.periods = n / 50;
    Channel stroke{"stroke", "m", "", {}}, force{"force", "N", "", {}}, pressure{"pressure", "Pa", "gauge", {}};
    for (int i = 0; i < n; ++i) {
      e.time.push_back(i / rate);
      stroke.samples.push_back(0.1 + 0.01 * std::sin(0.1 * i));
      force.samples.push_back(1000.0 * std::cos(0.1 * i) + (label[0] == 'q' ? 5000.0 : 0.0));
      pressure.samples.push_back(1e6);
    }
    e.channels = {stroke, force, pressure};
    s.experiments.push_back(std::move(e));
  }
  return s;
}

TEST(ReplayAcquisition, BlocksNeverSpanExperimentsAndCarryTheRecordedTimeAxisAndDerivedCounts) {
  const Session s = TwoRateSession();
  ReplayOptions o;
  o.block_sets = 64;
  ReplayAcquisition replay(s, o);
  replay.Start();
  EXPECT_EQ(replay.next_experiment(), 0u);
  EXPECT_EQ(replay.description().sample_rate, 200.0);
  std::vector<std::vector<AcquiredBlock>> blocks(2);
  while (!replay.finished()) {
    const std::size_t k = replay.next_experiment();
    AcquiredBlock b = replay.Read(100ms);
    ASSERT_FALSE(b.empty());
    ASSERT_LE(b.size(), 64u);
    blocks[k].push_back(std::move(b));
    if (k == 0 && !replay.finished() && replay.next_experiment() == 1) {
      EXPECT_EQ(blocks[0].back().time_ns.size() + (blocks[0].size() - 1) * 64, 400u);  // the last block of p
      EXPECT_EQ(replay.description().sample_rate, 500.0);
    }
  }
  EXPECT_TRUE(replay.Read(1s).empty());  // at the end: at once
  ASSERT_EQ(blocks[0].size(), 7u);       // 6 x 64 + 16: the boundary cuts a block short
  ASSERT_EQ(blocks[1].size(), 4u);
  const std::int64_t start = blocks[0][0].time_ns[0];
  std::uint64_t index = 0;
  for (std::size_t k = 0; k < 2; ++k) {
    const Experiment& e = s.experiments[k];
    std::size_t i = 0;
    for (const AcquiredBlock& b : blocks[k]) {
      EXPECT_EQ(b.first_index, index);  // consecutive from 0: the session has no sequence
      EXPECT_EQ(b.lost_before, 0u);
      EXPECT_TRUE(b.quality.valid());
      for (std::size_t j = 0; j < b.size(); ++j, ++i, ++index) {
        // p from 0, q one 200 Hz period after p's last sample (2 s).
        const std::int64_t expected = start + (k == 0 ? 0 : 2'000'000'000) + std::llround(e.time[i] * 1e9);
        ASSERT_EQ(b.time_ns[j], expected) << e.label << i;
        for (std::size_t c = 0; c < 3; ++c) {
          ASSERT_TRUE(SameBits(b.values[c][j], e.channels[c].samples[i]));
          // Counts derived from the values: the nearest count of a calibration over the session's range.
          const Calibration& cal = replay.experiments()[k].stream.channels[c].calibration;
          ASSERT_LE(std::abs(cal.ToSi(b.counts[c][j]) - b.values[c][j]), 0.5 * cal.gain * (1 + 1e-6)) << c;
        }
      }
    }
  }
  // One calibration per channel for the session: the CAN receiver's.
  EXPECT_EQ(replay.experiments()[0].stream.channels[1].calibration.gain,
            replay.experiments()[1].stream.channels[1].calibration.gain);
  EXPECT_EQ(replay.stats().sample_sets, 650u);
  EXPECT_NEAR(replay.recorded_seconds(), 2.0 + 0.5, 1e-12);
}

TEST(ReplayAcquisition, PacedReplayKeepsTheRecordedPaceOverTheSpeedAndNeverOverstaysATimeout) {
  ReplayOptions o;
  o.speed = 5.0;        // 2.5 s recorded in 0.5 s
  o.block_sets = 20;    // 100 ms recorded at 200 Hz: 20 ms of wall time
  ReplayAcquisition replay(TwoRateSession(), o);
  replay.Start();
  const std::int64_t started = MonotonicNs();
  std::int64_t longest_read = 0;
  std::size_t sets = 0, cut_short = 0;
  while (!replay.finished()) {
    const std::int64_t before = MonotonicNs();
    const AcquiredBlock b = replay.Read(3ms);
    const std::int64_t after = MonotonicNs();
    longest_read = std::max(longest_read, after - before);
    if (b.empty()) continue;
    sets += b.size();
    if (b.size() < 20 && replay.next_experiment() == 0) ++cut_short;
    // Never before the last sample of the block is due at that pace.
    const double due = static_cast<double>(b.time_ns.back() - started) / o.speed;
    ASSERT_GE(static_cast<double>(after - started), due - 2e6) << "a block came early";
  }
  const double wall = static_cast<double>(MonotonicNs() - started) / 1e9;
  EXPECT_EQ(sets, 650u);
  EXPECT_GT(cut_short, 0u);  // 3 ms timeouts within 20 ms blocks: the sets due by then
  EXPECT_GE(wall, 0.49);
  EXPECT_LT(wall, 5.0);
  EXPECT_LT(longest_read, 200'000'000) << "a Read overstayed its 3 ms timeout by far";

  // Nothing due within the timeout: an empty block after the timeout, not before, not much after.
  o.speed = 1e-3;  // the second sample is due 5 s after the first
  ReplayAcquisition slow(TwoRateSession(), o);
  slow.Start();
  EXPECT_EQ(slow.Read(5ms).size(), 1u);  // the first is due at Start
  const std::int64_t before = MonotonicNs();
  EXPECT_TRUE(slow.Read(5ms).empty());
  const std::int64_t waited = MonotonicNs() - before;
  EXPECT_GE(waited, 5'000'000);
  EXPECT_LT(waited, 200'000'000);
}

TEST(ReplayAcquisition, ReadBeforeStartAndBadOptionsAreErrors) {
  ReplayAcquisition replay(TwoRateSession());
  EXPECT_THROW(replay.Read(1ms), DeviceError);
  replay.Start();
  replay.Stop();
  EXPECT_THROW(replay.Read(1ms), DeviceError);
  for (double speed : {-1.0, std::nan(""), HUGE_VAL}) {
    ReplayOptions o;
    o.speed = speed;
    try {
      ReplayAcquisition bad(TwoRateSession(), o);
      FAIL() << "speed " << speed << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("speed"), std::string::npos) << e.what();
    }
  }
}

TEST(ReplayAcquisition, CountsThatNoRecorderWroteAreRefusedNamingTheExperimentAndChannel) {
  TempDir dir;
  Session s = ReadSession(RecordedSession(dir));
  Channel* counts = nullptr;
  for (Channel& c : s.experiments[1].channels)
    if (c.name == "force_counts") counts = &c;
  ASSERT_NE(counts, nullptr);
  counts->samples[3] = 1.5;
  try {
    ReplayAcquisition replay(s);
    FAIL() << "accepted";
  } catch (const SessionError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("experiment 'b'"), std::string::npos) << what;
    EXPECT_NE(what.find("'force_counts'"), std::string::npos) << what;
    EXPECT_NE(what.find("sample 3"), std::string::npos) << what;
  }
}

// A recorder's counts may be wider than a CAN sample frame's 16 bits: sending refuses them, naming
// the experiment, channel and sample; the counts derived for the other channels always fit.
TEST(ReplayCanOptions, RecordedCountsBeyondSixteenBitsAreRefusedNamingTheExperimentAndChannel) {
  TempDir dir;
  Session s = ReadSession(RecordedSession(dir));
  ReplayOptions o;
  o.speed = 1.0;
  EXPECT_NO_THROW(ReplayCanOptions(ReplayAcquisition(s, o)));  // derived pressure counts included
  for (Channel& c : s.experiments[2].channels)
    if (c.name == "stroke_counts") c.samples[7] = 40000.0;
  try {
    ReplayCanOptions(ReplayAcquisition(s, o));
    FAIL() << "accepted";
  } catch (const SessionError& e) {
    EXPECT_NE(std::string(e.what()).find("experiment 'c': channel 'stroke': count 40000 at sample 7 does not fit the 16 "
                                         "bits"),
              std::string::npos)
        << e.what();
  }
}

TEST(Replay, OverUdpTheSamplesArriveWithTheirCounts) {
  TempDir dir;
  ReplayOptions o;
  o.speed = 10.0;  // 650 sets at 200 Hz: 0.33 s
  auto replay = ReplayAcquisition::Open(RecordedSession(dir), o);
  const CanAcquisitionOptions can = ReplayCanOptions(*replay);
  EXPECT_EQ(can.sample_rate, 2000.0);  // the receiver's rate: recorded rate x speed
  EXPECT_FALSE(can.layout.fd);          // 2 kHz fits classic frames
  ASSERT_EQ(can.channels.size(), 3u);
  Receiver receiver(can);
  const ReplayFigures f = SendReplay(*replay, UdpCanTransport::Connect("127.0.0.1", receiver.port), can);
  receiver.Join();
  EXPECT_EQ(f.sample_sets, 650u);
  EXPECT_EQ(receiver.acquisition->stats().lost_sample_sets, 0u);
  EXPECT_EQ(receiver.acquisition->stats().corrupt_frames, 0u);
  const Session& s = replay->session();
  for (std::size_t c = 0; c < 3; ++c) {
    ASSERT_EQ(receiver.counts[c].size(), 650u) << c;
    std::size_t n = 0;
    for (std::size_t k = 0; k < 3; ++k) {
      const std::vector<std::int32_t>& sent = replay->counts(k, c);
      const Channel& si = s.experiments[k].channel(can.channels[c].name);
      for (std::size_t i = 0; i < sent.size(); ++i, ++n) {
        ASSERT_EQ(receiver.counts[c][n], sent[i]) << c << " " << n;  // counts exactly
        if (replay->experiments()[k].recorded_counts[c]) {
          // A CAN recording's SI values are its counts calibrated: they arrive exactly.
          ASSERT_TRUE(SameBits(receiver.values[c][n], si.samples[i])) << c << " " << n;
        } else {
          ASSERT_LE(std::abs(receiver.values[c][n] - si.samples[i]), 0.5 * can.channels[c].calibration.gain * (1 + 1e-6));
        }
      }
    }
  }
}

TEST(Replay, OverUdpFasterThanRealTimeEveryCountArrivesAtTheRateTimesTheSpeed) {
  // 100 s at 200 Hz sent at 1000 times the pace: a 200 kHz stream, CAN FD; a receiver at the
  // recorded rate would take the frames for a restarted module and drop most of them.
  Session s = TwoRateSession();
  s.experiments.pop_back();
  Experiment& e = s.experiments[0];
  const int n = 20000;
  e.time.clear();
  for (auto& c : e.channels) c.samples.clear();
  for (int i = 0; i < n; ++i) {
    e.time.push_back(i / 200.0);
    e.channels[0].samples.push_back(0.1 + 0.01 * std::sin(0.1 * i));
    e.channels[1].samples.push_back(1000.0 * std::cos(0.1 * i));
    e.channels[2].samples.push_back(1e6 + i);
  }
  e.periods = n / 50;
  ReplayOptions o;
  o.speed = 1000.0;
  ReplayAcquisition replay(s, o);
  const CanAcquisitionOptions can = ReplayCanOptions(replay);
  EXPECT_EQ(can.sample_rate, 200000.0);
  EXPECT_TRUE(can.layout.fd);
  Receiver receiver(can);
  SendReplay(replay, UdpCanTransport::Connect("127.0.0.1", receiver.port), can);
  receiver.Join();
  const AcquisitionStats& stats = receiver.acquisition->stats();
  EXPECT_EQ(stats.lost_sample_sets, 0u);
  EXPECT_EQ(stats.corrupt_frames, 0u);
  for (std::size_t c = 0; c < 3; ++c) {
    ASSERT_EQ(receiver.counts[c].size(), static_cast<std::size_t>(n)) << c;
    EXPECT_EQ(receiver.counts[c], replay.counts(0, c)) << c;
  }
  o.speed = 0.0;  // as fast as possible: no rate a receiver could check the frames against
  ReplayAcquisition fastest(s, o);
  EXPECT_THROW(ReplayCanOptions(fastest), std::invalid_argument);
}

}  // namespace
}  // namespace strut::daq
