// Starting values from the data and the friction pre-identification, on simulated sessions.
#include <gtest/gtest.h>

#include <cmath>

#include "strut/ident/estimator.h"
#include "strut/ident/initial_values.h"
#include "strut/sim/periodic_session.h"

namespace strut::ident {
namespace {

struct Fixture {
  ParameterSet truth = Model::Build("2dof", Causality::kStrokeInput).defaults();
  daq::Session session;
  Fixture() {
    sim::PeriodicSessionOptions options;
    options.seed = 21;
    session = sim::SimulatePeriodicSession("2dof", truth.values(), rig::StandardMatrix(), options);
  }
};

TEST(FrictionPreidentification, FindsTheArctanFrictionAtTheVelocityReversals) {
  const Fixture f;
  const auto data = PrepareExperiments(f.session, Causality::kStrokeInput, 800);
  const FrictionEstimate friction = PreidentifyFriction(data);
  ASSERT_TRUE(friction.ok) << friction.note;
  EXPECT_EQ(friction.reversals.size(), 28u);  // two per experiment
  EXPECT_NEAR(friction.base, f.truth.get("theta8"), 0.05 * f.truth.get("theta8"));
  EXPECT_NEAR(friction.per_pressure, f.truth.get("theta9"), 0.10 * f.truth.get("theta9"));
  EXPECT_NEAR(friction.sharpness, f.truth.get("theta10"), 0.25 * f.truth.get("theta10"));
  // The amplitude grows with pressure (paper Fig. 7): compare the extremes.
  const auto [low, high] = std::minmax_element(
      friction.reversals.begin(), friction.reversals.end(),
      [](const FrictionReversal& a, const FrictionReversal& b) { return a.pressure < b.pressure; });
  EXPECT_GT(high->amplitude, low->amplitude);
}

TEST(InitialValues, StartCloseEnoughForTheFitToReachTheTruth) {
  const Fixture f;
  const Model model = Model::Build("2dof", Causality::kStrokeInput);
  const auto data = PrepareExperiments(f.session, model.causality(), 800);
  std::vector<std::string> log;
  const ParameterSet start = InitialValuesFromData(model, data, &log);
  EXPECT_EQ(static_cast<int>(log.size()), start.size());  // every parameter says where it came from
  for (const char* name : {"theta4", "theta5", "theta6"})
    EXPECT_NEAR(start.get(name), f.truth.get(name), 0.03 * std::abs(f.truth.get(name))) << name;
  EXPECT_NEAR(start.get("theta11"), f.truth.get("theta11"), 30.0);
  // Every parameter the data determine, from there.
  const FitSummary fit = Estimator(model).Fit(data, start, DefaultChoices(start));
  ASSERT_TRUE(fit.converged) << fit.FullReport();
  EXPECT_NEAR(fit.parameters.get("theta16"), f.truth.get("theta16"), 0.02 * f.truth.get("theta16"));
  EXPECT_NEAR(fit.parameters.get("theta4"), f.truth.get("theta4"), 0.002 * f.truth.get("theta4"));
}

TEST(InitialValues, OneDofGetsItsPolytropicExponentFromTheSlowestTest) {
  const ParameterSet truth = Model::Build("1dof", Causality::kStrokeInput).defaults();
  const daq::Session session = sim::SimulatePeriodicSession("1dof", truth.values(), rig::StandardMatrix(), {});
  const Model model = Model::Build("1dof", Causality::kForceInput);
  const ParameterSet start = InitialValuesFromData(model, PrepareExperiments(session, model.causality(), 400), nullptr);
  EXPECT_NEAR(start.get("theta7"), truth.get("theta7"), 0.03);
  EXPECT_NEAR(start.get("theta6"), truth.get("theta6"), 0.05 * std::abs(truth.get("theta6")));
  EXPECT_NEAR(start.get("theta5"), truth.get("theta5"), 0.03 * truth.get("theta5"));
}

}  // namespace
}  // namespace strut::ident
