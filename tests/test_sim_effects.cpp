// Every switchable effect of the truth changes the rig's outputs in the expected direction, and
// only where it should. Each run: the rig with an ideal actuator and ideal sensors, the same seed
// (same start phase), with and without the effect; the clean record is compared sample by sample.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "strut/sim/simulated_rig.h"

namespace strut::sim {
namespace {

enum Row { kStroke = 0, kForce = 1, kPressure = 2 };

Truth Base(std::vector<std::string> effects) {
  Truth t = DefaultTruth();
  t.effects = std::move(effects);
  t.actuator.ideal = true;
  for (SensorOptions* s : {&t.sensors.stroke, &t.sensors.force, &t.sensors.pressure}) {
    s->noise = 0.0, s->offset = 0.0, s->gain_error = 0.0, s->bits = 0;
  }
  t.acquisition.gauge_pressure = false;
  t.acquisition.settle_tolerance = 1e-6;
  t.acquisition.rtol = 1e-9;
  return t;
}

const std::vector<std::string> k2dof = {"heat-exchange", "gas-solubility"};

std::vector<std::string> With(std::string effect) {
  std::vector<std::string> e = k2dof;
  e.push_back(std::move(effect));
  return e;
}

PeriodicRunReport Simulate(const Truth& truth, const rig::MatrixEntry& entry, double rate = 200.0) {
  const SimulatedRig rig(truth);
  std::mt19937_64 rng(11);
  PeriodicRunReport report;
  rig.RunPeriodic(entry, rate, 1, rng, &report);
  EXPECT_TRUE(report.settled) << entry.label;
  return report;
}

Eigen::VectorXd RowOf(const PeriodicRunReport& r, int row) { return r.clean.row(row).transpose(); }

//! Stroke rate from the ideal actuator's set-point (the stroke is the set-point).
Eigen::VectorXd Velocity(const PeriodicRunReport& r, const rig::MatrixEntry& e, double rate) {
  Eigen::VectorXd v(r.clean.cols());
  const double w = 2 * M_PI * e.frequency;
  for (Eigen::Index i = 0; i < v.size(); ++i) v[i] = e.amplitude * w * std::cos(w * i / rate + r.start_phase);
  return v;
}

//! Work done on the gas over the recorded period, integral of p A dq (J), trapezoidal.
double LoopWork(const PeriodicRunReport& r, double area) {
  const Eigen::VectorXd q = RowOf(r, kStroke), p = RowOf(r, kPressure);
  double w = 0.0;
  const Eigen::Index n = q.size();
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Index j = (i + 1) % n;
    w += 0.5 * (p[i] + p[j]) * area * (q[j] - q[i]);
  }
  return w;
}

const rig::MatrixEntry kA{"a", "middle", 0.04, 0.133, 0.127};
const rig::MatrixEntry kB{"b", "middle", 0.10, 0.133, 0.127};
const rig::MatrixEntry kF{"f", "high", 2.0, 0.249, 0.010};
const rig::MatrixEntry kK{"k", "low", 0.2, 0.080, 0.079};
const rig::MatrixEntry kN{"n", "low", 2.0, 0.014, 0.010};

TEST(SimEffects, HeatExchangeOpensAPressureStrokeLoopThatShrinksWithFrequency) {
  const double area = 5.0e-3;
  const double w_a = LoopWork(Simulate(Base(k2dof), kA), area), w_b = LoopWork(Simulate(Base(k2dof), kB), area);
  const double w_poly = LoopWork(Simulate(Base({}), kA), area);  // heat-exchange off: polytropic 1 dof
  std::printf("  gas loop work per cycle: 2dof %.1f J at 0.04 Hz, %.1f J at 0.1 Hz; polytropic %.3f J\n", w_a, w_b,
              w_poly);
  EXPECT_GT(w_a, 30.0);         // heat leaves through the wall: damper-physics.md §1.6 gives 88 J (tau 8 s)
  EXPECT_GT(w_a, 1.5 * w_b);    // above the thermal corner the loop shrinks with frequency
  EXPECT_GT(w_b, 10.0);
  EXPECT_LT(std::abs(w_poly), 0.05);  // a polytropic gas has no loop
}

TEST(SimEffects, GasSolubilityLowersThePressureMostWhereItIsHighest) {
  const auto relative = [&](const rig::MatrixEntry& e) {
    const PeriodicRunReport on = Simulate(Base(k2dof), e), off = Simulate(Base({"heat-exchange"}), e);
    return ((RowOf(on, kPressure) - RowOf(off, kPressure)).array() / RowOf(off, kPressure).array()).mean();
  };
  const double deep = relative(kF), extended = relative(kN);
  std::printf("  solubility: mean pressure change %.4f %% (f, high) and %.4f %% (n, low)\n", 100 * deep, 100 * extended);
  EXPECT_LT(deep, 0.0);
  EXPECT_LT(extended, 0.0);
  EXPECT_LT(deep, 3.0 * extended);  // several times more at high pressure
}

TEST(SimEffects, OilCompressibilitySoftensOnlyTheDeepCompression) {
  const auto relative = [&](const rig::MatrixEntry& e) {
    const PeriodicRunReport on = Simulate(Base(With("oil-compressibility")), e), off = Simulate(Base(k2dof), e);
    return ((RowOf(on, kPressure) - RowOf(off, kPressure)).array() / RowOf(off, kPressure).array()).mean();
  };
  const double deep = relative(kF), extended = relative(kN);
  std::printf("  oil compliance: mean pressure change %.4f %% (f) and %.4f %% (n)\n", 100 * deep, 100 * extended);
  EXPECT_LT(deep, -0.01);                // the gas gets room: 2 % softer at 5 MPa
  EXPECT_LT(std::abs(extended), 2e-4);  // near the charge pressure nothing changes
}

TEST(SimEffects, RealGasStiffensWhereTheGasIsDenseAndHot) {
  const PeriodicRunReport on = Simulate(Base(With("real-gas")), kA), off = Simulate(Base(k2dof), kA);
  const Eigen::VectorXd p_on = RowOf(on, kPressure), p_off = RowOf(off, kPressure);
  Eigen::Index peak = 0, low = 0;
  p_off.maxCoeff(&peak);
  p_off.minCoeff(&low);
  std::printf("  real gas: %+.3f %% at the pressure peak, %+.3f %% at the lowest pressure\n",
              100 * (p_on[peak] / p_off[peak] - 1), 100 * (p_on[low] / p_off[low] - 1));
  EXPECT_GT(p_on[peak] / p_off[peak] - 1, 0.01);  // Z > 1 at 6.7 MPa and 390 K
  EXPECT_LT(p_on[low] / p_off[low] - 1, 0.0);     // Z < 1 near the charge at ambient (B < 0)
  EXPECT_GT(p_on[low] / p_off[low] - 1, -0.003);
}

TEST(SimEffects, ViscousDampingAddsAForceInPhaseWithTheStrokeRate) {
  const PeriodicRunReport on = Simulate(Base(With("viscous-damping")), kF), off = Simulate(Base(k2dof), kF);
  const Eigen::VectorXd added = RowOf(on, kForce) - RowOf(off, kForce);
  const Eigen::VectorXd expected = 300.0 * Velocity(on, kF, 200.0);
  EXPECT_LT((added - expected).cwiseAbs().maxCoeff(), 0.05);
  EXPECT_NEAR(added.cwiseAbs().maxCoeff(), 300.0 * 0.010 * 2 * M_PI * 2.0, 0.5);
  EXPECT_LT((RowOf(on, kPressure) - RowOf(off, kPressure)).cwiseAbs().maxCoeff(), 1.0);  // the gas does not notice
}

TEST(SimEffects, StribeckFrictionRaisesTheForceOnlyNearVelocityReversals) {
  const PeriodicRunReport on = Simulate(Base(With("stribeck-friction")), kK), off = Simulate(Base(k2dof), kK);
  const Eigen::VectorXd added = RowOf(on, kForce) - RowOf(off, kForce), v = Velocity(on, kK, 200.0);
  double peak_slow = 0.0, peak_fast = 0.0, against = 0.0;
  for (Eigen::Index i = 0; i < v.size(); ++i) {
    if (std::abs(v[i]) < 0.009) peak_slow = std::max(peak_slow, std::abs(added[i]));
    if (std::abs(v[i]) > 0.03) peak_fast = std::max(peak_fast, std::abs(added[i]));
    against = std::min(against, added[i] * (v[i] > 0 ? 1.0 : -1.0));  // the extra force opposes the motion
  }
  std::printf("  Stribeck: up to %.1f N within 9 mm/s of a reversal, %.3f N above 30 mm/s\n", peak_slow, peak_fast);
  EXPECT_GT(peak_slow, 30.0);
  EXPECT_LT(peak_fast, 0.05);
  EXPECT_GT(against, -0.05);
}

TEST(SimEffects, EndStopActsOnlyNearFullExtension) {
  // The standard matrix stays at least 3 mm inside full extension (true stroke = LVDT + 2 mm).
  for (const rig::MatrixEntry& e : {kN, kK}) {
    const PeriodicRunReport on = Simulate(Base(With("end-stop")), e), off = Simulate(Base(k2dof), e);
    EXPECT_LT((RowOf(on, kForce) - RowOf(off, kForce)).cwiseAbs().maxCoeff(), 0.01) << e.label;
  }
  // An over-travelled sine reaches 3 mm beyond full extension: the stop pulls hard there, only there.
  const rig::MatrixEntry over{"over", "low", 0.5, 0.010, 0.015};
  const PeriodicRunReport on = Simulate(Base(With("end-stop")), over), off = Simulate(Base(k2dof), over);
  const Eigen::VectorXd added = RowOf(on, kForce) - RowOf(off, kForce), measured = RowOf(on, kStroke);
  double inside = 0.0;
  for (Eigen::Index i = 0; i < added.size(); ++i)
    if (measured[i] + 0.002 > 0.0015) inside = std::max(inside, std::abs(added[i]));
  std::printf("  end stop: %.0f N at the deepest over-travel, %.3f N beyond 1.5 mm inside\n", added.minCoeff(), inside);
  EXPECT_LT(added.minCoeff(), -5000.0);
  EXPECT_LT(inside, 1.0);
}

}  // namespace
}  // namespace strut::sim
