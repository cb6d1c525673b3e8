// Drop tests on the simulated rig: a 350 kg mass meets the fully extended damper at 0.5 m/s
// (method.md §7); the gas heats, the mass stays compressed, and the gas cools back to ambient with
// the documented thermal time constant.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "strut/sim/simulated_rig.h"

namespace strut::sim {
namespace {

TEST(SimDrop, GasCoolsWithTheDocumentedThermalTimeConstant) {
  const SimulatedRig rig(DefaultTruth());
  std::mt19937_64 rng(1);
  DropRunReport report;
  rig.RunDrop(DropSpec{}, rng, &report);
  std::printf("  drop: peak %.1f mm, end %.1f mm; time constant %.2f s fitted, %.2f s model\n", report.peak_stroke * 1e3,
              report.final_stroke * 1e3, report.thermal_time_constant_fit, report.thermal_time_constant_model);
  // theta15 / (theta16 (1 + theta6 q)) = 17.9 / (1.79 (1 - 3.33 * 0.04)) = 11.5 s (docs/simulated-rig.md).
  EXPECT_NEAR(report.thermal_time_constant_model, 11.5, 0.3);
  EXPECT_NEAR(report.thermal_time_constant_fit, report.thermal_time_constant_model,
              0.06 * report.thermal_time_constant_model);
  // damper-physics.md §1.6: about 40 mm at the end of the stroke, still compressed 30 s later.
  EXPECT_GT(report.peak_stroke, 0.035);
  EXPECT_LT(report.peak_stroke, 0.046);
  EXPECT_GT(report.final_stroke, 0.033);
  // The gas heats by 5-20 K and 30 s later (2.6 time constants) keeps less than a tenth of that.
  const Eigen::VectorXd T = report.result.channel("temperature");
  EXPECT_GT(T.maxCoeff() - 293.15, 5.0);
  EXPECT_LT(T.maxCoeff() - 293.15, 20.0);
  EXPECT_LT(std::abs(T[T.size() - 1] - 293.15), 0.1 * (T.maxCoeff() - 293.15));
}

TEST(SimDrop, SessionIsAContractDropExperiment) {
  const SimulatedRig rig(DefaultTruth());
  DropSpec drop;
  drop.duration = 3.0;
  drop.label = "d350";
  const daq::Session s = rig.RunDropSession(drop);
  EXPECT_TRUE(daq::Validate(s).empty());
  ASSERT_EQ(s.experiments.size(), 1u);
  const daq::Experiment& e = s.experiments[0];
  EXPECT_EQ(e.kind, daq::ExperimentKind::kDrop);
  EXPECT_EQ(e.label, "d350");
  EXPECT_DOUBLE_EQ(e.drop_mass, 350.0);
  EXPECT_DOUBLE_EQ(e.impact_velocity, 0.5);
  EXPECT_DOUBLE_EQ(e.sample_rate, 1000.0);
  EXPECT_EQ(e.sample_count(), 3001u);
  EXPECT_EQ(e.channel("pressure").reference, "gauge");
  EXPECT_EQ(e.channel("force").units, "N");
  // At rest the load cell carries the mass (plus its zero and gain error): about 3.43 kN.
  const auto& f = e.channel("force").samples;
  double mean = 0;
  for (std::size_t i = f.size() - 500; i < f.size(); ++i) mean += f[i] / 500;
  EXPECT_NEAR(mean, 1.002 * 350 * 9.81 + 60.0, 5.0);
  // The LVDT starts at full extension: its reading is the stroke offset.
  EXPECT_NEAR(e.channel("stroke").samples[0], -0.002 * 1.001, 2e-4);
  EXPECT_THROW(rig.RunDropSession(DropSpec{"x", -1.0, 0.5, 1.0}), std::invalid_argument);
}

}  // namespace
}  // namespace strut::sim
