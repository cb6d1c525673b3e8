// The rig runner's standalone units: steady-state detection (rig/steady_state.h) on synthetic
// cycles whose changes are known, and the safety detectors, limits file and matrix check
// (rig/safety.h) against hand-computed values and a periodic solution of a fitted model.
#include <gtest/gtest.h>
#include <spdlog/fmt/fmt.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>

#include "strut/ident/fit_record.h"
#include "strut/ident/model.h"
#include "strut/ident/periodic.h"
#include "strut/rig/channel_file.h"
#include "strut/rig/safety.h"
#include "strut/rig/steady_state.h"
#include "test_support.h"

namespace strut::rig {
namespace {

// Samples of `cycles` cycles of n samples: stroke = 0.1 + 0.02 sin, force = amplitude (1 + decay^c) sin + 500,
// pressure = 2e6 (1 + drift c): cycle c's force peak differs from the last by a known amount.
struct Synthetic {
  std::vector<std::int64_t> t;
  std::vector<double> stroke, force, pressure;
};
Synthetic Make(int cycles, int n, double decay, double drift = 0.0) {
  Synthetic s;
  for (int c = 0; c < cycles; ++c) {
    for (int i = 0; i < n; ++i) {
      const double phase = 2.0 * std::numbers::pi * (i + 0.5) / n;
      s.t.push_back((static_cast<std::int64_t>(c) * n + i) * 1'000'000);
      s.stroke.push_back(0.1 + 0.02 * std::sin(phase));
      s.force.push_back(1e4 * (1.0 + std::pow(decay, c)) * std::sin(phase) + 500.0);
      s.pressure.push_back(2e6 * (1.0 + drift * c));
    }
  }
  return s;
}

// The whole cycles of n samples in `s`, summarised in one go.
std::vector<CycleSummary> Summarised(const Synthetic& s, int n) {
  return CycleSummariser(n).Add(s.t, s.stroke, s.force, s.pressure);
}

TEST(CycleSummariser, CutsWholeCyclesTheSameWhateverTheBlocks) {
  const Synthetic s = Make(5, 100, 0.5);
  CycleSummariser whole(100);
  const auto all = whole.Add(s.t, s.stroke, s.force, s.pressure);
  ASSERT_EQ(all.size(), 5u);
  CycleSummariser pieces(100);
  std::vector<CycleSummary> got;
  for (std::size_t at = 0, k = 7; at < s.t.size(); at += k, k = k * 3 % 41 + 1) {
    const std::size_t n = std::min(k, s.t.size() - at);
    for (const auto& c : pieces.Add(std::span(s.t).subspan(at, n), std::span(s.stroke).subspan(at, n),
                                    std::span(s.force).subspan(at, n), std::span(s.pressure).subspan(at, n)))
      got.push_back(c);
  }
  ASSERT_EQ(got.size(), all.size());
  for (std::size_t c = 0; c < all.size(); ++c) {
    EXPECT_EQ(got[c].cycle, static_cast<long>(c));
    EXPECT_EQ(got[c].start_ns, all[c].start_ns);
    EXPECT_DOUBLE_EQ(got[c].force_max, all[c].force_max);
    EXPECT_DOUBLE_EQ(got[c].pressure_mean, all[c].pressure_mean);
  }
  // Against the formula: the peak of the cycle's samples and the trough.
  const double peak = 1e4 * (1.0 + std::pow(0.5, 2)) * std::sin(2 * std::numbers::pi * 24.5 / 100) + 500.0;
  EXPECT_NEAR(all[2].force_max, peak, 1e-9);
  EXPECT_NEAR(all[2].stroke_amplitude(), 0.02 * std::sin(2 * std::numbers::pi * 24.5 / 100), 1e-12);
  EXPECT_NEAR(all[3].pressure_mean, 2e6, 1e-6);
}

TEST(SteadyState, SteadyWhenTheConsecutiveChangesAreWithinTolerance) {
  // Force peaks relax by half each cycle: the change between cycles c-1 and c relative to cycle c's
  // force range is 0.5^c / (2 (1 + 0.5^c)): 1.5 % between cycles 4 and 5, 0.77 % between 5 and 6.
  const Synthetic s = Make(20, 64, 0.5);
  const auto cycles = Summarised(s, 64);
  SteadyStateTolerances t;
  t.consecutive = 2;
  t.drift_window = 0.0;  // these cycles last 64 ms: the thermal drift test has its own below
  const SteadyStateVerdict v = DetectSteadyState(cycles, t);
  EXPECT_TRUE(v.steady);
  EXPECT_FALSE(v.timed_out);
  // Changes 5->6 and 6->7 agree: steady after cycle 7.
  EXPECT_EQ(v.steady_at, 7);
  EXPECT_LT(v.measure, 1.0);
  // The change itself against the formula.
  const auto expected = [](int c) { return std::pow(0.5, c) / (2.0 * (1.0 + std::pow(0.5, c))); };
  EXPECT_NEAR(ChangeBetween(cycles[4], cycles[5], t).force, expected(5), 1e-12);
  EXPECT_NEAR(ChangeBetween(cycles[5], cycles[6], t).force, expected(6), 1e-12);
  EXPECT_GT(expected(5), 0.01);
  EXPECT_LT(expected(6), 0.01);
}

TEST(SteadyState, ADriftingResponseTimesOutAtTheCycleOrTimeLimit) {
  const Synthetic s = Make(30, 50, 0.0, 0.02);  // pressure drifts 2 % a cycle: never steady
  const auto cycles = Summarised(s, 50);
  SteadyStateTolerances t;
  t.max_cycles = 12;
  t.drift_window = 0.0;
  SteadyStateVerdict v = DetectSteadyState(cycles, t);
  EXPECT_FALSE(v.steady);
  EXPECT_TRUE(v.timed_out);
  EXPECT_EQ(v.cycles, 12);
  EXPECT_GT(v.measure, 1.0);
  // The time limit: cycles of 50 ms, 0.3 s is reached at the end of cycle 6 (its last sample at 349 ms).
  t.max_cycles = 100;
  t.time_limit = 0.3;
  v = DetectSteadyState(cycles, t);
  EXPECT_TRUE(v.timed_out);
  EXPECT_EQ(v.cycles, 7);
  // Without pressure, the same record is steady (its force and stroke do not change).
  CycleSummariser no_pressure(50);
  const auto dry = no_pressure.Add(s.t, s.stroke, s.force, {});
  EXPECT_TRUE(std::isnan(dry[0].pressure_mean));
  EXPECT_TRUE(DetectSteadyState(dry, t).steady);
}

TEST(SteadyState, ASlowThermalDriftWithinTheCycleToleranceIsNotSteadyUntilItHasDecayed) {
  // Cycles of 0.5 s (a 2 Hz test), the mean pressure relaxing as 2 MPa (1 + 0.05 exp(-t / 40 s)),
  // the gas near full compression: consecutive cycles differ by at most 0.06 %, far within the
  // 0.5 % cycle tolerance, but the drift over the 30 s window up to t is 2e-4 of the mean only once
  // 0.05 exp(-t/40) (exp(30/40) - 1) <= 2e-4, at t = 40 ln(0.05 x 1.117 / 2e-4) = 225.3 s.
  const int n = 50, cycles_count = 800;
  const double period = 0.5, tau = 40.0;
  Synthetic s;
  for (int c = 0; c < cycles_count; ++c)
    for (int i = 0; i < n; ++i) {
      const double time = (c * n + i) * period / n;
      s.t.push_back(static_cast<std::int64_t>(std::llround(time * 1e9)));
      const double phase = 2.0 * std::numbers::pi * (i + 0.5) / n;
      s.stroke.push_back(0.2 + 0.01 * std::sin(phase));
      s.force.push_back(1e4 * std::sin(phase) + 500.0);
      s.pressure.push_back(2e6 * (1.0 + 0.05 * std::exp(-time / tau)));
    }
  const auto cycles = Summarised(s, n);
  SteadyStateTolerances t;
  t.max_cycles = 100000;
  const SteadyStateVerdict v = DetectSteadyState(cycles, t);
  ASSERT_TRUE(v.steady) << v.cycles << " " << v.measure;
  // The cycle mean of exp(-t/tau) shifts the moment by under a cycle; the window's cycle ends
  // round it up to the next whole cycle.
  const double expected = tau * std::log(0.05 * (std::exp(30.0 / tau) - 1.0) / 2e-4);
  EXPECT_NEAR((v.steady_at + 1) * period, expected, 1.5) << v.steady_at;
  // Without the drift test (window 0) the per-cycle tolerance passes at once.
  t.drift_window = 0.0;
  EXPECT_LT(DetectSteadyState(cycles, t).steady_at, 5);
}

TEST(SteadyState, CyclesRoundTripThroughASessionGroupAndGiveTheSameVerdict) {
  const Synthetic s = Make(12, 40, 0.6);
  const auto cycles = Summarised(s, 40);
  SteadyStateTolerances t;
  t.force = 0.02;
  const SteadyStateVerdict v = DetectSteadyState(cycles, t);
  const daq::MetadataGroup g = CyclesGroup("a", cycles, v, t);
  const auto back = CyclesFromGroup(g);
  ASSERT_EQ(back.size(), cycles.size());
  EXPECT_DOUBLE_EQ(back[4].force_max, cycles[4].force_max);
  EXPECT_EQ(back[4].start_ns, cycles[4].start_ns);
  const SteadyStateTolerances t2 = TolerancesFromGroup(g);
  EXPECT_DOUBLE_EQ(t2.force, 0.02);
  const SteadyStateVerdict again = DetectSteadyState(back, t2);
  EXPECT_EQ(again.steady, v.steady);
  EXPECT_EQ(again.steady_at, v.steady_at);
  daq::MetadataGroup broken = g;
  broken.groups[1].attributes.erase("force_max");
  EXPECT_THROW(CyclesFromGroup(broken), daq::SessionError);
  SteadyStateTolerances bad;
  bad.force = 0.0;
  EXPECT_THROW(SteadyStateDetector{bad}, std::invalid_argument);
}

TEST(ChannelFile, ConvertsTheCalibrationSheetsUnitsToSiAndPlacesEveryReading) {
  const ChannelMap m = ParseChannelFile(R"(module = 7
frame = "fd"
channels = 5
[stroke]
index = 3
unit = "mm"
gain = 0.005
offset = 150.0
[force]
index = 2
unit = "kN"
gain = -0.002
[pressure]
index = 0
unit = "bar"
gain = 0.004
offset = 100.0
range_min = -1.0
range_max = 200.0
reference = "absolute"
)", "c.toml");
  EXPECT_EQ(m.layout.module, 7);
  EXPECT_TRUE(m.layout.fd);
  EXPECT_EQ(m.layout.channels, 5);
  ASSERT_EQ(m.channels.size(), 5u);
  EXPECT_EQ(m.channels[0].name, "pressure");
  EXPECT_EQ(m.channels[1].name, "channel1");
  EXPECT_EQ(m.channels[2].name, "force");
  EXPECT_EQ(m.channels[3].name, "stroke");
  EXPECT_EQ(m.channels[4].name, "channel4");
  EXPECT_EQ(m.pressure_reference, "absolute");
  // 0.005 mm = 5 um a count about 150 mm; the range the 16-bit counts span: 150 mm -+ 32768 x 5 um.
  const daq::Calibration& stroke = m.channels[3].calibration;
  EXPECT_EQ(m.channels[3].unit, "m");
  EXPECT_DOUBLE_EQ(stroke.gain, 5e-6);
  EXPECT_DOUBLE_EQ(stroke.offset, 0.15);
  EXPECT_DOUBLE_EQ(stroke.range_min, 0.15 - 32768 * 5e-6);
  EXPECT_DOUBLE_EQ(stroke.range_max, 0.15 + 32767 * 5e-6);
  EXPECT_DOUBLE_EQ(stroke.ToSi(1000), 0.155);
  // A negative gain (a load cell wired the other way) keeps the range ordered.
  const daq::Calibration& force = m.channels[2].calibration;
  EXPECT_DOUBLE_EQ(force.gain, -2.0);
  EXPECT_DOUBLE_EQ(force.range_min, -2.0 * 32767);
  EXPECT_DOUBLE_EQ(force.range_max, 2.0 * 32768);
  // 1 bar = 1e5 Pa; the given range in bar.
  const daq::Calibration& pressure = m.channels[0].calibration;
  EXPECT_EQ(m.channels[0].unit, "Pa");
  EXPECT_DOUBLE_EQ(pressure.gain, 400.0);
  EXPECT_DOUBLE_EQ(pressure.offset, 1e7);
  EXPECT_DOUBLE_EQ(pressure.range_min, -1e5);
  EXPECT_DOUBLE_EQ(pressure.range_max, 2e7);
  // The readings nobody named are kept in counts.
  EXPECT_DOUBLE_EQ(m.channels[1].calibration.ToSi(1234), 1234.0);
  EXPECT_EQ(m.channels[1].unit, "1");
  // The receiver takes the map as it is.
  daq::CanAcquisitionOptions o;
  o.layout = m.layout;
  o.channels = m.channels;
  std::string error;
  EXPECT_TRUE(o.IsValid(&error)) << error;
  // Pressure is optional; without `channels` the set ends at the highest index.
  const ChannelMap two = ParseChannelFile(
      "module = 0\nframe = \"classic\"\n[force]\nindex = 0\nunit = \"N\"\ngain = 1.0\n[stroke]\nindex = 1\nunit = "
      "\"m\"\ngain = 1e-5\n", "d.toml");
  EXPECT_EQ(two.layout.channels, 2);
  EXPECT_FALSE(two.layout.fd);
  EXPECT_EQ(two.pressure_reference, "gauge");
  EXPECT_THROW(ParseChannelFile("module = 64\nframe = \"fd\"\n", "e.toml"), ChannelFileError);
}

TEST(SafetyConfig, ReadsALimitsFileAndNamesTheLineOfEveryMistake) {
  const SafetyConfig c = ParseSafetyConfig(R"(
[stroke]
lower = 0.0
upper = 0.25
persistence = 5
action = "stop"
[force]
enabled = false
[stale]
timeout = 0.2
[lag]
max_lag = 1.5
action = "stop"
[actuator]
max_velocity = 0.3
)",
                                           "limits.toml");
  EXPECT_DOUBLE_EQ(c.stroke.upper, 0.25);
  EXPECT_EQ(c.stroke.persistence, 5);
  EXPECT_EQ(c.stroke.action, SafetyAction::kStop);
  EXPECT_FALSE(c.force.enabled);
  EXPECT_EQ(c.stale.timeout.count(), 200);
  ASSERT_TRUE(c.lag.max_lag.has_value());
  EXPECT_EQ(c.lag.max_lag->count(), 1500);
  EXPECT_EQ(c.lag.action, SafetyAction::kStop);
  EXPECT_FALSE(ParseSafetyConfig("[lag]\nenabled = true\n", "l.toml").lag.max_lag.has_value());  // the speed's default
  EXPECT_DOUBLE_EQ(c.actuator.max_velocity, 0.3);
  EXPECT_EQ(c.pressure.action, SafetyAction::kInterlock);  // defaults stay
  const auto error = [](const char* text) {
    return test::ErrorOf<SafetyError>([&] { ParseSafetyConfig(text, "l.toml"); });
  };
  EXPECT_EQ(error("[stroke]\nupper = 0.2\naction = \"flee\"\n"),
            "l.toml:3: [stroke] action must be \"indicate\", \"hold\", \"stop\" or \"interlock\"");
  EXPECT_NE(error("[stroke]\nuper = 0.2\n").find("l.toml:2: [stroke] unknown key 'uper'"), std::string::npos);
  EXPECT_NE(error("[strok]\n").find("l.toml:1: unknown section 'strok'"), std::string::npos);
  EXPECT_NE(error("[stroke]\nlower = 0.3\n").find("[stroke] lower 0.3 must be below upper 0.27"), std::string::npos);
  EXPECT_NE(error("[force]\nupper = \"lots\"\n").find("l.toml:2: [force] upper: expected a number, got the string \"lots\""), std::string::npos);
  EXPECT_NE(error("[force\n").find("l.toml:1:"), std::string::npos);
}

daq::AcquiredBlock Block(std::vector<double> stroke, std::vector<double> force, std::int64_t t0 = 0) {
  daq::AcquiredBlock b;
  for (std::size_t i = 0; i < stroke.size(); ++i) b.time_ns.push_back(t0 + static_cast<std::int64_t>(i) * 1'000'000);
  b.values = {std::move(stroke), std::move(force)};
  return b;
}

TEST(SafetyMonitor, ALimitTripsAfterItsPersistenceOnEitherSideAndLatches) {
  SafetyConfig c;
  c.stroke = {true, 0.0, 0.2, 3, SafetyAction::kStop};
  c.force = {true, -1000.0, 1000.0, 1, SafetyAction::kIndicate};
  SafetyMonitor m(c, {"stroke", "force"});
  // Two samples above, one back inside, two above: never three in a row.
  EXPECT_TRUE(m.CheckBlock(Block({0.21, 0.21, 0.1, 0.21, 0.21}, {0, 0, 0, 0, 0})).empty());
  auto trips = m.CheckBlock(Block({0.1, 0.1, -0.01, -0.02, -0.03, -0.04}, {0, 0, 0, 0, 0, 0}, 10'000'000));
  ASSERT_EQ(trips.size(), 1u);
  EXPECT_EQ(trips[0].detector, "stroke-limit");
  EXPECT_EQ(trips[0].action, SafetyAction::kStop);
  EXPECT_EQ(trips[0].monotonic_ns, 14'000'000);  // the third sample below
  EXPECT_EQ(trips[0].text, "stroke -0.03 m below the limit 0 m for 3 samples");
  // Latched: no second trip until Reset; the force limit trips on its first sample.
  trips = m.CheckBlock(Block({-0.05, -0.05, -0.05}, {0, 1500, 0}));
  ASSERT_EQ(trips.size(), 1u);
  EXPECT_EQ(trips[0].detector, "force-limit");
  EXPECT_EQ(trips[0].action, SafetyAction::kIndicate);
  const Margins margins = m.TakeMargins();
  EXPECT_LT(margins.stroke, 0.0);
  m.Reset(0);
  EXPECT_EQ(m.CheckBlock(Block({-0.05, -0.05, -0.05}, {0, 0, 0})).size(), 1u);
}

// The limited channels are found by name wherever the layout puts them, once; a channel of no
// limit is not checked, and trips come in the blocks' channel order.
TEST(SafetyMonitor, FindsTheLimitedChannelsWhereverTheLayoutPutsThem) {
  SafetyConfig c;
  c.stroke = {true, 0.0, 0.2, 1, SafetyAction::kStop};
  c.force = {true, -1000.0, 1000.0, 1, SafetyAction::kIndicate};
  c.pressure = {true, 0.0, 1e6, 1, SafetyAction::kHold};
  SafetyMonitor m(c, {"pressure", "temperature", "force", "stroke"});
  daq::AcquiredBlock b;
  b.time_ns = {0, 1'000'000};
  b.values = {{5e5, 2e6}, {-1e9, 1e9}, {0.0, 1500.0}, {0.1, 0.3}};
  const std::vector<Trip> trips = m.CheckBlock(b);
  ASSERT_EQ(trips.size(), 3u);
  EXPECT_EQ(trips[0].text, "pressure 2e+06 Pa above the limit 1e+06 Pa for 1 samples");
  EXPECT_EQ(trips[1].text, "force 1500 N above the limit 1000 N for 1 samples");
  EXPECT_EQ(trips[2].text, "stroke 0.3 m above the limit 0.2 m for 1 samples");
  const Margins margins = m.TakeMargins();
  EXPECT_DOUBLE_EQ(margins.pressure, (1e6 - 2e6) / 5e5);
  EXPECT_DOUBLE_EQ(margins.force, (1000.0 - 1500.0) / 1000.0);
  EXPECT_DOUBLE_EQ(margins.stroke, (0.2 - 0.3) / 0.1);
  // A block of fewer channels than the layout: the missing ones are not read.
  daq::AcquiredBlock short_block;
  short_block.time_ns = {2'000'000};
  short_block.values = {{5e5}};
  m.Reset(0);
  EXPECT_TRUE(m.CheckBlock(short_block).empty());
}

TEST(SafetyMonitor, FollowingErrorHeartbeatFaultStaleAndUnderPeak) {
  SafetyConfig c;
  c.following.max_error = 0.002;
  c.following.persistence = 2;
  c.heartbeat.controller_timeout = std::chrono::milliseconds(100);
  c.stale.timeout = std::chrono::milliseconds(50);
  c.under_peak.fraction = 0.9;
  c.under_peak.cycles = 2;
  SafetyMonitor m(c, {"stroke", "force"});
  m.Arm(0);
  daq::ControllerStatus s;
  s.state = daq::ControllerState::kRunning;
  s.command = 0.105;
  s.stroke = 0.1;
  s.heartbeat = 1;
  EXPECT_TRUE(m.CheckStatus(s, 0).empty());
  s.heartbeat = 2;
  auto trips = m.CheckStatus(s, 10'000'000);
  ASSERT_EQ(trips.size(), 1u);
  EXPECT_EQ(trips[0].detector, "following-error");
  EXPECT_EQ(trips[0].action, SafetyAction::kStop);
  // The heartbeat stays at 2 from 10 ms: trips at 110 ms, not at 100 ms.
  EXPECT_TRUE(m.CheckStatus(s, 100'000'000).empty());
  trips = m.CheckStatus(s, 110'000'000);
  ASSERT_EQ(trips.size(), 1u);
  EXPECT_EQ(trips[0].detector, "controller-heartbeat");
  EXPECT_EQ(trips[0].action, SafetyAction::kInterlock);
  s.fault_word = daq::fault_bits::kForceLimit;
  trips = m.CheckStatus(s, 120'000'000);
  ASSERT_EQ(trips.size(), 1u);
  EXPECT_EQ(trips[0].detector, "controller-fault");
  EXPECT_NE(trips[0].text.find("force-limit"), std::string::npos);
  // Stale: the last sample at 9 ms (a block of 10 from 0), timeout 50 ms.
  m.CheckBlock(Block(std::vector<double>(10, 0.1), std::vector<double>(10, 0.0)));
  EXPECT_FALSE(m.CheckStale(58'000'000));
  const auto stale = m.CheckStale(59'000'000);
  ASSERT_TRUE(stale);
  EXPECT_EQ(stale->detector, "stale-data");
  // Silence counts from the samples' arrival: samples timed 0..9 ms whose last frame came at 40 ms
  // are stale at 90 ms, not at 59 ms. Their lag behind their own clock (31 ms) is the lag
  // detector's: within 40 ms nothing, beyond 30 ms a trip that says what lags.
  c.lag.max_lag = std::chrono::milliseconds(40);
  SafetyMonitor behind(c, {"stroke", "force"});
  behind.Arm(0);
  daq::AcquiredBlock late = Block(std::vector<double>(10, 0.1), std::vector<double>(10, 0.0));
  late.last_frame_ns = 40'000'000;
  EXPECT_TRUE(behind.CheckBlock(late).empty());
  EXPECT_EQ(behind.largest_lag_ns(), 31'000'000);
  EXPECT_FALSE(behind.CheckStale(89'000'000));
  EXPECT_TRUE(behind.CheckStale(90'000'000));
  c.lag.max_lag = std::chrono::milliseconds(30);
  for (const double speed : {1.0, 50.0}) {
    SafetyMonitor lagging(c, {"stroke", "force"}, speed);
    lagging.Arm(0);
    const std::vector<Trip> trips = lagging.CheckBlock(late);
    ASSERT_EQ(trips.size(), 1u);
    EXPECT_EQ(trips[0].detector, "stream-lag");
    EXPECT_EQ(trips[0].action, SafetyAction::kHold);
    EXPECT_NE(trips[0].text.find("31 ms behind their own clock (limit 30 ms)"), std::string::npos) << trips[0].text;
    EXPECT_EQ(trips[0].text.find("cannot hold 50x real time") != std::string::npos, speed == 50.0) << trips[0].text;
    EXPECT_TRUE(lagging.CheckBlock(late).empty());  // latched
  }
  // The default limit: half a second for a stream at its recorded rate, 3 s for an accelerated one.
  EXPECT_EQ(SafetyMonitor(SafetyConfig{}, {"stroke", "force"}).max_lag().count(), 500);
  EXPECT_EQ(SafetyMonitor(SafetyConfig{}, {"stroke", "force"}, 50.0).max_lag().count(), 3000);
  // Under-peak: 0.85 of the commanded amplitude for two cycles.
  CycleSummary cycle;
  cycle.stroke_min = 0.1 - 0.0085;
  cycle.stroke_max = 0.1 + 0.0085;
  EXPECT_FALSE(m.CheckCycle(cycle, 0.01, 0));
  const auto under = m.CheckCycle(cycle, 0.01, 1);
  ASSERT_TRUE(under);
  EXPECT_EQ(under->detector, "under-peak");
  EXPECT_NE(under->text.find("85.0 %"), std::string::npos);
}

TEST(CheckMatrix, RefusesStrokeRangeVelocityFlowAndRateNamingTheExperiment) {
  SafetyConfig c;
  EXPECT_TRUE(CheckMatrix(StandardMatrix(), c, 200.0).empty());
  std::vector<MatrixEntry> m = {{"ok", "middle", 1.0, 0.13, 0.02},
                                {"deep", "high", 0.5, 0.26, 0.02},
                                {"fast", "middle", 10.0, 0.13, 0.02},
                                {"odd", "middle", 3.0, 0.13, 0.001}};
  c.actuator.max_velocity = 1.0;
  c.actuator.piston_area = 0.01;
  c.actuator.max_flow = 2e-3;  // 0.2 m/s at this area
  const auto refusals = CheckMatrix(m, c, 200.0);
  ASSERT_EQ(refusals.size(), 4u) << fmt::format("{}", fmt::join(refusals, "\n"));
  EXPECT_EQ(refusals[0], "experiment 'deep': stroke 0.24 .. 0.28 m leaves the stroke limit -0.008 .. 0.27 m");
  // 2 pi 10 Hz 0.02 m = 1.2566 m/s; flow 0.012566 m^3/s.
  EXPECT_EQ(refusals[1], "experiment 'fast': peak velocity 2 pi f A = 1.257 m/s exceeds the velocity limit 1 m/s");
  EXPECT_NE(refusals[2].find("experiment 'fast': actuator flow 0.01257 m^3/s"), std::string::npos);
  // 'ok' at 1 Hz: 0.126 m/s x 0.01 m^2 = 1.26e-3 m^3/s, within the supply; 'odd': 66.7 samples a period.
  EXPECT_NE(refusals[3].find("experiment 'odd': 3 Hz sampled at 200 Hz is not a whole number"), std::string::npos);
}

TEST(CheckMatrix, RefusesAForceThePeriodicSolverPredictsFromAFit) {
  // A fit of the 2dof model at its defaults, under stroke input as the rig drives it.
  const ident::Model model = ident::Model::Build("2dof", ident::Causality::kStrokeInput);
  nlohmann::json j{{"model", "2dof"}, {"converged", true}, {"verdict", "at-noise-floor"}};
  const auto& d = model.defaults();
  for (int i = 0; i < d.size(); ++i)
    j["parameters"].push_back({{"index", d.spec(i).key()}, {"value", d.value(i)}, {"sd", nullptr}, {"estimated", false}});
  const ident::FitRecord fit = ident::ParseFitJson(j, "fit.json", ident::Causality::kStrokeInput);
  const MatrixEntry e{"c", "high", 0.2, 0.179, 0.075};
  // The independent reference: the periodic solver called directly.
  ident::PeriodicSolver solver(model);
  const auto solution = solver.Solve(ident::PeriodicInput::Sine(0.2, 0.179, 0.075, 256), d.values());
  const Eigen::VectorXd force = solution.channel("force");
  const double peak = force.maxCoeff();
  ASSERT_GT(peak, 1000.0);
  const ResponsePredictor predict = FitPredictor(fit);
  EXPECT_NEAR(predict(e).force_max, peak, 1e-6 * std::abs(peak));

  SafetyConfig c;
  c.force.upper = 1.1 * peak;
  c.pressure.enabled = false;
  EXPECT_TRUE(CheckMatrix({e}, c, 200.0, predict).empty());
  c.force.upper = 0.9 * peak;
  const auto refusals = CheckMatrix({e}, c, 200.0, predict);
  ASSERT_EQ(refusals.size(), 1u);
  EXPECT_NE(refusals[0].find("experiment 'c': predicted force"), std::string::npos) << refusals[0];
  EXPECT_NE(refusals[0].find("leaves the force limit"), std::string::npos) << refusals[0];
}

}  // namespace
}  // namespace strut::rig
