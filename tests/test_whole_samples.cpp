// daq::WholeSamplesPerPeriod: the one "whole samples per period" test of the generators, the rig
// and the fit, with its one tolerance (daq::kWholeSamplesTolerance).
#include <gtest/gtest.h>

#include <cmath>

#include "strut/daq/session.h"
#include "strut/ident/experiment_data.h"
#include "strut/ident/model.h"
#include "strut/rig/test_matrix.h"
#include "strut/sim/periodic_session.h"

namespace {

using strut::daq::kWholeSamplesTolerance;
using strut::daq::WholeSamplesPerPeriod;

TEST(WholeSamples, GivesTheCountOfAWholeRatio) {
  EXPECT_EQ(WholeSamplesPerPeriod(2000.0, 10.0), 200);
  EXPECT_EQ(WholeSamplesPerPeriod(2000.0, 0.25), 8000);
  // Decimal inputs whose quotient is not exact in binary still count as whole.
  EXPECT_EQ(WholeSamplesPerPeriod(1000.0, 1000.0 / 7.0), 7);
  EXPECT_EQ(WholeSamplesPerPeriod(1e7 / 16384.0, 1e7 / 16384.0 / 8192.0), 8192);  // the Silverbox record
  EXPECT_EQ(WholeSamplesPerPeriod(300.0, 0.1 * 3), 1000);  // 0.1 * 3 is 0.30000000000000004
}

TEST(WholeSamples, RefusesAFractionBeyondTheTolerance) {
  EXPECT_FALSE(WholeSamplesPerPeriod(2000.0, 3.0));  // 666.67
  const double n = 200.0;
  // Inside and outside the relative tolerance, on either side.
  EXPECT_EQ(WholeSamplesPerPeriod(n * (1 + 0.5 * kWholeSamplesTolerance), 1.0), 200);
  EXPECT_EQ(WholeSamplesPerPeriod(n * (1 - 0.5 * kWholeSamplesTolerance), 1.0), 200);
  EXPECT_FALSE(WholeSamplesPerPeriod(n * (1 + 2 * kWholeSamplesTolerance), 1.0));
  EXPECT_FALSE(WholeSamplesPerPeriod(n * (1 - 2 * kWholeSamplesTolerance), 1.0));
  // A measured rate a millionth off is not whole: over 100 periods it drifts 0.02 samples.
  EXPECT_FALSE(WholeSamplesPerPeriod(2000.0 * (1 + 1e-7), 10.0));
}

TEST(WholeSamples, HoldsTheCallersMinimum) {
  EXPECT_EQ(WholeSamplesPerPeriod(160.0, 10.0, 16), 16);
  EXPECT_FALSE(WholeSamplesPerPeriod(150.0, 10.0, 16));
  EXPECT_EQ(WholeSamplesPerPeriod(20.0, 10.0, 2), 2);
  EXPECT_FALSE(WholeSamplesPerPeriod(10.0, 10.0, 2));
  EXPECT_FALSE(WholeSamplesPerPeriod(4.0, 10.0));  // 0.4: rounds to no sample at all
}

TEST(WholeSamples, RefusesRatesAndFrequenciesThatAreNotPositive) {
  EXPECT_FALSE(WholeSamplesPerPeriod(0.0, 10.0));
  EXPECT_FALSE(WholeSamplesPerPeriod(2000.0, 0.0));
  EXPECT_FALSE(WholeSamplesPerPeriod(-2000.0, -10.0));
  EXPECT_FALSE(WholeSamplesPerPeriod(NAN, 10.0));
  EXPECT_FALSE(WholeSamplesPerPeriod(2000.0, NAN));
}

// The fit averages the recorded samples phase by phase only when the rate gives whole samples per
// period by this same test; a rate a tenth of a ppm off (beyond the tolerance) is resampled onto
// the n-point grid instead, since its phases drift through the record.
TEST(WholeSamples, TheFitAveragesRecordedPhasesOnlyAtWholeSamples) {
  using namespace strut;
  const ident::Model model = ident::Model::Build("2dof", ident::Causality::kStrokeInput);
  const rig::MatrixEntry entry = rig::StandardMatrix().front();
  const daq::Session whole =
      sim::SimulatePeriodicSession("2dof", model.defaults().values(), {entry}, sim::PeriodicSessionOptions{});
  const long native = *WholeSamplesPerPeriod(whole.experiments[0].sample_rate, entry.frequency);
  daq::Session drifting = whole;
  drifting.experiments[0].sample_rate *= 1 + 1e-7;
  ASSERT_FALSE(WholeSamplesPerPeriod(drifting.experiments[0].sample_rate, entry.frequency));
  const int n = 3 * static_cast<int>(native);
  EXPECT_EQ(ident::PrepareExperiments(whole, model, n).at(0).phases.size(), static_cast<std::size_t>(native));
  EXPECT_EQ(ident::PrepareExperiments(drifting, model, n).at(0).phases.size(), static_cast<std::size_t>(n));
}

}  // namespace
