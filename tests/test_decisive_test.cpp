// The test that decides between two fitted models (ident/decisive_test.h): its predicted difference
// against a long transient integration of both models (IDA), the space's limits kept, and nothing
// proposed between a model and itself.
#include <gtest/gtest.h>

#include <cmath>

#include "session_fixtures.h"
#include "strut/ident/decisive_test.h"
#include "strut/sim/transient.h"
#include "transient_reference.h"

namespace strut::ident {
namespace {

constexpr int kGrid = 400;

// A fit record of `composition` at its defaults with `changes`: what ProposeDecisiveTest reads of a fit.
FitSummary FitAt(const std::string& composition, const std::string& changes) {
  FitSummary fit;
  fit.model = composition;
  fit.parameters = Model::Build(composition, Causality::kStrokeInput).defaults();
  if (!changes.empty()) fit.parameters.apply_assignments(changes);
  fit.converged = true;
  return fit;
}

const std::vector<ExperimentData>& StandardExperimentsData() {
  static const std::vector<ExperimentData> experiments = test::SimulatedFitData("2dof", "", 3, kGrid).experiments;
  return experiments;
}

TestSpace StandardSpace() { return TestSpaceOf(StandardExperimentsData()); }

// The RMS over a period of the steady-state difference of `channel` between two parameter sets,
// from IDA integrated until consecutive periods agree.
double ReferenceRmsDifference(const std::string& composition, const std::string& changes_a, const std::string& changes_b,
                              const DecisiveTest& t, const std::string& channel) {
  const Model model = Model::Build(composition, Causality::kStrokeInput);
  const PeriodicInput input = PeriodicInput::Sine(t.frequency, t.static_position, t.amplitude, 512);
  sim::SteadyStateOptions steady;
  steady.tol = 0.1;
  steady.periods_max = 400;
  const sim::TransientSimulator simulator(model, test::ReferenceTolerances());
  const auto solve = [&](const std::string& changes) {
    ParameterSet theta = model.defaults();
    if (!changes.empty()) theta.apply_assignments(changes);
    return simulator.PeriodicSteadyState(theta.values(), input, steady).solution.channel(channel);
  };
  const Eigen::VectorXd d = solve(changes_a) - solve(changes_b);
  return std::sqrt(d.squaredNorm() / static_cast<double>(d.size()));
}

TEST(DecisiveTest, SpaceOfTheStandardMatrixIsItsEnvelope) {
  const TestSpace s = StandardSpace();
  double low = 1.0, high = 0.0, rate = 0.0;
  for (const ExperimentData& e : StandardExperimentsData()) {
    low = std::min(low, e.static_position - e.amplitude);
    high = std::max(high, e.static_position + e.amplitude);
    rate = std::max(rate, 2 * M_PI * e.frequency * e.amplitude);
    EXPECT_EQ(e.sample_rate, 200.0) << e.label;
  }
  EXPECT_EQ(s.stroke_min, low);
  EXPECT_EQ(s.stroke_max, high);
  EXPECT_EQ(s.max_rate, rate);
  EXPECT_EQ(s.sample_rate, 200.0);
  for (const double static_position : s.static_positions)
    EXPECT_TRUE(static_position > low && static_position < high) << static_position;
  EXPECT_EQ(s.frequencies, (std::vector<double>{0.04, 0.1, 0.2, 0.5, 1.0, 2.0}));
  EXPECT_GT(s.noise_sd.at("force"), 0.0);
  EXPECT_GT(s.noise_sd.at("pressure"), 0.0);
  std::string error;
  EXPECT_TRUE(s.IsValid(&error)) << error;
}

TEST(DecisiveTest, PredictedDifferenceMatchesTheTransientReference) {
  // Oil compressibility against none: they part at high pressure.
  const std::string model = "2dof+oil-compressibility";
  const FitSummary a = FitAt(model, "theta26=1e-9"), b = FitAt(model, "theta26=0");
  const auto t = ProposeDecisiveTest(a, b, StandardSpace());
  ASSERT_TRUE(t.has_value());
  std::printf("  %s\n", t->Describe().c_str());
  EXPECT_GT(t->separation, 100.0);
  EXPECT_NEAR(t->separation_per_minute * t->minutes, t->separation, 1e-9 * t->separation);
  for (const std::string channel : {"force", "pressure"}) {
    const double reference = ReferenceRmsDifference(model, "theta26=1e-9", "theta26=0", *t, channel);
    const double predicted = t->rms_difference.at(channel) * StandardSpace().noise_sd.at(channel);
    EXPECT_NEAR(predicted, reference, 0.03 * reference + 1e-9) << channel;
  }
  // Within the space: the stroke range, the peak rate.
  const TestSpace s = StandardSpace();
  EXPECT_GE(t->static_position - t->amplitude, s.stroke_min - 1e-12);
  EXPECT_LE(t->static_position + t->amplitude, s.stroke_max + 1e-12);
  EXPECT_LE(2 * M_PI * t->frequency * t->amplitude, s.max_rate * (1 + 1e-12));
}

TEST(DecisiveTest, KeepsWithinThePressureLimit) {
  const std::string model = "2dof+oil-compressibility";
  const FitSummary a = FitAt(model, "theta26=1e-9"), b = FitAt(model, "theta26=0");
  const auto unlimited = ProposeDecisiveTest(a, b, StandardSpace());
  ASSERT_TRUE(unlimited.has_value());
  TestSpace limited = StandardSpace();
  limited.max_pressure = 0.7 * unlimited->peak.at("pressure");
  const auto t = ProposeDecisiveTest(a, b, limited);
  ASSERT_TRUE(t.has_value());
  EXPECT_LE(t->peak.at("pressure"), limited.max_pressure);
  EXPECT_LT(t->separation_per_minute, unlimited->separation_per_minute);
}

TEST(DecisiveTest, NothingSeparatesAModelFromItself) {
  const FitSummary a = FitAt("2dof", "");
  const auto t = ProposeDecisiveTest(a, a, StandardSpace());
  ASSERT_TRUE(t.has_value());
  EXPECT_EQ(t->separation, 0.0);
}

FitSummary FitWithBic(double bic, bool converged) {
  FitSummary f;
  f.experiments.resize(1);
  f.experiments.front().converged = true;
  f.loglik = -0.5 * bic;
  f.bic = bic;
  f.converged = converged;
  return f;
}

TEST(DecisiveTest, AWinnerOnlyWhenEveryModelsFitConverged) {
  const std::vector<std::string> models{"2dof+dead-volume", "2dof+pressure-heat-transfer"};
  const Decision clear = DecideByBic(models, {FitWithBic(100.0, true), FitWithBic(150.0, true)});
  EXPECT_EQ(clear.winner, 0);
  EXPECT_DOUBLE_EQ(clear.delta_bic, 50.0);
  EXPECT_EQ(DecideByBic(models, {FitWithBic(100.0, true), FitWithBic(105.0, true)}).winner, -1);
  // The rival stopped short, far above: its own best may still be below the first's.
  const Decision unfinished = DecideByBic(models, {FitWithBic(100.0, true), FitWithBic(500.0, false)});
  EXPECT_EQ(unfinished.winner, -1);
  EXPECT_NE(unfinished.conclusion.find("2dof+pressure-heat-transfer did not converge"), std::string::npos)
      << unfinished.conclusion;
  EXPECT_THROW(DecideByBic({models[0]}, {FitWithBic(100.0, true)}), std::invalid_argument);
}

TEST(DecisiveTest, RefusesASpaceWithoutNoise) {
  TestSpace s = StandardSpace();
  s.noise_sd.clear();
  try {
    ProposeDecisiveTest(FitAt("2dof", ""), FitAt("2dof", ""), s);
    FAIL() << "a space without noise cannot weigh a difference";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("noise sd"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace strut::ident
