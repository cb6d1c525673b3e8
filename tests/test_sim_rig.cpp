// The simulated rig as a real one looks from outside: sessions of whole steady-state periods in SI
// with gauge pressure, reproducible by seed, with injected faults where they were asked for,
// samples streamed in order and paced by the clock, and limits flagged.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>

#include "strut/daq/session.h"
#include "strut/sim/simulated_rig.h"
#include "test_support.h"

namespace strut::sim {
namespace {

rig::MatrixPlan Small() {
  rig::MatrixPlan plan;
  plan.experiments = {{"d", "high", 0.5, 0.219, 0.032}, {"h", "middle", 0.5, 0.133, 0.034}, {"n", "low", 2.0, 0.014, 0.010}};
  return plan;
}

TEST(SimRig, SessionHoldsWholeSteadyPeriodsInSIWithGaugePressure) {
  const SimulatedRig rig(DefaultTruth());
  std::vector<PeriodicRunReport> reports;
  const daq::Session s = rig.RunMatrix(Small(), {}, &reports);
  EXPECT_TRUE(daq::Validate(s).empty());
  EXPECT_EQ(s.damper_serial, "SIM-F16N-0001");
  ASSERT_EQ(s.experiments.size(), 3u);
  for (std::size_t k = 0; k < s.experiments.size(); ++k) {
    const daq::Experiment& e = s.experiments[k];
    SCOPED_TRACE(e.label);
    EXPECT_EQ(e.kind, daq::ExperimentKind::kPeriodic);
    EXPECT_EQ(e.periods, 3);
    EXPECT_EQ(static_cast<double>(e.sample_count()), 3 * 200.0 / e.frequency);
    EXPECT_DOUBLE_EQ(e.time[0], 0.0);
    EXPECT_EQ(e.channel("stroke").units, "m");
    EXPECT_EQ(e.channel("force").units, "N");
    EXPECT_EQ(e.channel("pressure").units, "Pa");
    EXPECT_EQ(e.channel("pressure").reference, "gauge");
    EXPECT_EQ(e.extra_attributes.at("sim_settled"), "true");
    EXPECT_TRUE(reports[k].settled);
    EXPECT_LT(reports[k].record_change, 1e-4);
    // The stroke reading is the set-point sine (tracking error, LVDT noise) around the static position.
    const auto& q = e.channel("stroke").samples;
    const auto [lo, hi] = std::minmax_element(q.begin(), q.end());
    EXPECT_NEAR(0.5 * (*hi + *lo), e.static_position, 5e-4);
    EXPECT_NEAR(0.5 * (*hi - *lo), e.amplitude, 1e-3);
    // Periods repeat to within the noise: compare the first and the last recorded period.
    const auto& p = e.channel("pressure").samples;
    const std::size_t n = e.sample_count() / 3;
    double diff = 0;
    for (std::size_t i = 0; i < n; ++i) diff += std::pow(p[i] - p[i + 2 * n], 2) / n;
    EXPECT_LT(std::sqrt(diff), 2.0 * std::sqrt(2.0) * 2.0e3);  // two noise realisations of 2 kPa
  }
  // Gauge pressure of the charge region: about 0.5-0.7 MPa at the low position.
  const auto& p_n = s.experiments[2].channel("pressure").samples;
  EXPECT_GT(*std::min_element(p_n.begin(), p_n.end()), 0.45e6);
  EXPECT_LT(*std::max_element(p_n.begin(), p_n.end()), 0.70e6);
}

TEST(SimRig, SameSeedGivesTheSameSessionAndAnotherSeedAnother) {
  const SimulatedRig rig(DefaultTruth());
  rig::MatrixPlan plan;
  plan.experiments = {{"n", "low", 2.0, 0.014, 0.010}};
  RigRunOptions one, two;
  one.seed = 5, two.seed = 6;
  const daq::Session a = rig.RunMatrix(plan, one), b = rig.RunMatrix(plan, one), c = rig.RunMatrix(plan, two);
  EXPECT_EQ(a.experiments[0].channel("force").samples, b.experiments[0].channel("force").samples);
  EXPECT_NE(a.experiments[0].channel("force").samples, c.experiments[0].channel("force").samples);
  EXPECT_NE(a.experiments[0].extra_attributes.at("sim_start_phase"), c.experiments[0].extra_attributes.at("sim_start_phase"));
}

TEST(SimRig, InjectedFaultsShowWhereTheyWereAsked) {
  Truth t = DefaultTruth();
  t.faults = {FaultSpec{"h", "pressure", FaultKind::kDropout, 1.0, 0.5},
              FaultSpec{"h", "force", FaultKind::kStuck, 3.0, 0.0},
              FaultSpec{"n", "stroke", FaultKind::kDisconnected, 0.0, 0.0}};
  const SimulatedRig rig(t);
  const daq::Session s = rig.RunMatrix(Small());
  EXPECT_TRUE(daq::Validate(s).empty());
  const daq::Experiment& h = s.experiment("h");
  const auto& p = h.channel("pressure").samples;
  for (int i = 200; i < 300; ++i) EXPECT_LT(std::abs(p[i]), 10e3) << i;  // dropped out to zero (noise 2 kPa)
  EXPECT_GT(p[199], 0.8e6);
  EXPECT_GT(p[300], 0.8e6);
  const auto& f = h.channel("force").samples;
  for (std::size_t i = 600; i < f.size(); ++i) EXPECT_EQ(f[i], f[600]);
  EXPECT_NE(f[599], f[600]);
  for (double v : s.experiment("n").channel("stroke").samples) EXPECT_DOUBLE_EQ(v, -0.010);  // the lower rail
  // Experiment d has none of them.
  const auto& d = s.experiment("d").channel("stroke").samples;
  EXPECT_GT(*std::min_element(d.begin(), d.end()), 0.15);
}

// A matrix of experiment j of the standard matrix alone (middle position, 2 Hz, 10 mm).
rig::MatrixPlan OnlyExperimentJ() {
  rig::MatrixPlan plan;
  plan.experiments = {{"j", "middle", 2.0, 0.133, 0.010}};
  return plan;
}

TEST(SimRig, StreamedSamplesArriveInOrderAndTheRecordedOnesAreTheSession) {
  const SimulatedRig rig(DefaultTruth());
  const rig::MatrixPlan plan = OnlyExperimentJ();
  std::vector<SampleBlock> blocks;
  RigRunOptions o;
  o.sink = [&](const SampleBlock& b) { blocks.push_back(b); };
  const daq::Session s = rig.RunMatrix(plan, o);
  ASSERT_FALSE(blocks.empty());
  double t = 0.0;
  std::vector<double> recorded;
  for (const SampleBlock& b : blocks) {
    EXPECT_NEAR(b.start_time, t, 1e-9);
    EXPECT_LE(b.stroke.size(), 20u);  // 0.1 s pieces
    t += b.stroke.size() / b.sample_rate;
    if (b.recording) recorded.insert(recorded.end(), b.force.begin(), b.force.end());
  }
  EXPECT_FALSE(blocks.front().recording);  // settling comes first
  EXPECT_EQ(recorded, s.experiments[0].channel("force").samples);
}

TEST(SimRig, RealTimeClockPacesTheRun) {
  const SimulatedRig rig(DefaultTruth());
  const rig::MatrixPlan plan = OnlyExperimentJ();
  std::vector<PeriodicRunReport> reports;
  RigRunOptions o;
  o.clock = {ClockMode::kRealTime, 20.0};  // 20 simulated seconds per wall second
  const auto start = std::chrono::steady_clock::now();
  rig.RunMatrix(plan, o, &reports);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_GE(wall, reports[0].simulated_seconds / 20.0 - 0.01);
  EXPECT_LT(wall, reports[0].simulated_seconds / 20.0 + 3.0);  // computing j takes 0.05 s
}

TEST(SimRig, LimitsAreFlaggedAndBadMatricesRefused) {
  const SimulatedRig rig(DefaultTruth());
  rig::MatrixPlan plan;
  plan.experiments = {{"fast", "middle", 2.0, 0.133, 0.050}};  // needs 0.63 m/s, the valve gives 0.4
  std::vector<PeriodicRunReport> reports;
  const daq::Session s = rig.RunMatrix(plan, {}, &reports);
  EXPECT_GT(reports[0].actuator.saturated_fraction, 0.1);
  EXPECT_GT(reports[0].actuator.max_tracking_error, 0.005);
  const auto& q = s.experiments[0].channel("stroke").samples;
  EXPECT_LT(0.5 * (*std::max_element(q.begin(), q.end()) - *std::min_element(q.begin(), q.end())), 0.95 * 0.050);

  // The force-limit interlock stops a test that loads the actuator too hard: aborted, no periods.
  Truth weak = DefaultTruth();
  weak.actuator.stall_force = 22e3, weak.actuator.force_limit = 20e3;
  rig::MatrixPlan deep;
  deep.experiments = {{"f", "high", 2.0, 0.249, 0.010}, {"n", "low", 2.0, 0.014, 0.010}};
  const daq::Session stopped = SimulatedRig(weak).RunMatrix(deep);
  EXPECT_TRUE(daq::Validate(stopped).empty());
  EXPECT_EQ(stopped.experiment("f").status, "aborted");
  EXPECT_EQ(stopped.experiment("f").periods, 0);
  EXPECT_NE(stopped.experiment("f").extra_attributes.at("sim_interlock").find("force limit 20.0 kN"), std::string::npos);
  EXPECT_LT(stopped.experiment("f").sample_count(), 100u);
  EXPECT_EQ(stopped.experiment("n").status, "complete");  // 4 kN: the next test runs

  rig::MatrixPlan odd;
  odd.experiments = {{"odd", "", 0.3, 0.133, 0.01}};  // 200 / 0.3 samples per period
  try {
    rig.RunMatrix(odd);
    FAIL();
  } catch (const TruthError& e) {
    EXPECT_NE(std::string(e.what()).find("'odd'"), std::string::npos);
  }
}

}  // namespace
}  // namespace strut::sim
