// The noise floor as a test on the noise ratio's sampling distribution (estimator.h,
// docs/discovery.md "The noise floor test"): the predicted sd against the spread of the ratio over
// independent noise realisations of a right model, and a misfit under the old fixed 1.2 that the
// test sees and discovery then names.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <numeric>

#include "strut/ident/discover.h"
#include "session_fixtures.h"

namespace strut::ident {
namespace {

constexpr int kGrid = 400;

FitData Simulate(const std::string& truth_model, const std::string& changes, unsigned seed) {
  return test::SimulatedFitData(truth_model, changes, seed, kGrid);
}

SessionFitOptions Options(const std::string& composition) { return test::FitOptionsOnGrid(composition, kGrid); }

TEST(NoiseFloor, UpperNormalQuantileMatchesTheTable) {
  EXPECT_NEAR(UpperNormalQuantile(0.5), 0.0, 1e-12);
  EXPECT_NEAR(UpperNormalQuantile(0.025), 1.959963984540054, 1e-9);
  EXPECT_NEAR(UpperNormalQuantile(5e-4), 3.290526731491926, 1e-9);
  EXPECT_NEAR(UpperNormalQuantile(0.975), -1.959963984540054, 1e-9);
  EXPECT_THROW(UpperNormalQuantile(0.0), std::invalid_argument);
  EXPECT_THROW(UpperNormalQuantile(1.0), std::invalid_argument);
  EXPECT_NEAR(NoiseFloorLimit(0.01, 2), 1.0 + 3.290526731491926 * 0.01, 1e-9);
  EXPECT_EQ(NoiseFloorLimit(NAN, 2), kNoiseFloorRatio);
}

TEST(NoiseFloor, ThePredictedSdIsTheSpreadOfTheRatioOverNoiseRealisations) {
  // A right model fitted to 12 realisations of the same unit's noise: the ratios scatter around 1
  // with the sd FitProblem::NoiseRatioStatistics predicts. With 12 draws the sample sd lies within a
  // factor 0.5-1.6 of the true one with probability above 0.999 (chi-square with 11 dof).
  const Model model = Model::Build("2dof", Causality::kStrokeInput);
  std::map<std::string, std::vector<double>> ratios;
  std::map<std::string, double> predicted;
  for (unsigned seed = 100; seed < 112; ++seed) {
    const FitData data = Simulate("2dof", "", seed);
    const FitSummary fit = FitPrepared(data, model, Options("2dof")).summary;
    ASSERT_TRUE(fit.converged) << seed;
    for (const FitChannel& c : fit.channels) {
      ratios[c.name].push_back(c.noise_ratio);
      predicted[c.name] = c.noise_ratio_sd;
      EXPECT_GT(c.noise_floor_limit, 1.0);
      EXPECT_LT(c.noise_floor_limit, 1.1);  // thousands of samples: far under the old fixed 1.2
    }
    EXPECT_EQ(fit.Verdict(), FitVerdict::kAtNoiseFloor) << seed;
  }
  for (const auto& [channel, r] : ratios) {
    const double mean = std::accumulate(r.begin(), r.end(), 0.0) / r.size();
    double ss = 0.0;
    for (double x : r) ss += (x - mean) * (x - mean);
    const double sd = std::sqrt(ss / (r.size() - 1));
    SCOPED_TRACE(channel);
    EXPECT_GT(predicted[channel], 0.005);
    EXPECT_LT(predicted[channel], 0.05);
    EXPECT_GT(sd, 0.5 * predicted[channel]);
    EXPECT_LT(sd, 1.6 * predicted[channel]);
    // The mean lies within 4 standard errors of 1 (the model is right).
    EXPECT_NEAR(mean, 1.0, 4.0 * predicted[channel] / std::sqrt(r.size()) + 0.01);
  }
}

TEST(NoiseFloor, AMisfitUnderTheFixedFloorIsAboveTheNoiseAndDiscoveryNamesIt) {
  // Friction 10 % higher in compression than in extension: the 2 dof fit's pooled force ratio
  // stays well under 1.2, many sd above 1.
  const FitData data = Simulate("2dof+friction-asymmetry", "theta34=0.1", 21);
  const FitSummary fit = FitPrepared(data, Model::Build("2dof", Causality::kStrokeInput), Options("2dof")).summary;
  ASSERT_TRUE(fit.converged);
  const auto force = std::find_if(fit.channels.begin(), fit.channels.end(), [](const FitChannel& c) { return c.name == "force"; });
  ASSERT_NE(force, fit.channels.end());
  EXPECT_LT(force->noise_ratio, kNoiseFloorRatio);
  EXPECT_GT((force->noise_ratio - 1.0) / force->noise_ratio_sd, 4.0);
  EXPECT_EQ(fit.Verdict(), FitVerdict::kAboveNoiseFloor);
  const DiscoveryResult r = Discover(data, Options("2dof"), DiscoverOptions());
  EXPECT_FALSE(r.nothing_missing);
  ASSERT_EQ(r.missing.size(), 1u) << r.conclusion;
  EXPECT_EQ(r.missing.front(), "friction-asymmetry");
  EXPECT_EQ(r.final_fit.Verdict(), FitVerdict::kAtNoiseFloor) << r.conclusion;
}

}  // namespace
}  // namespace strut::ident
