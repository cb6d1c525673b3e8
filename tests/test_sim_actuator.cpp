// The servo-hydraulic actuator in stroke control: tracking with a small phase lag, saturation of
// large fast strokes at the flow limit, stalling at the force limit; and the smooth stroke
// signals the damper integrator is fed.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "strut/sim/actuator.h"

namespace strut::sim {
namespace {

constexpr double kPi = std::numbers::pi;

struct Fundamental {
  double amplitude, phase;  // of sin(w t + phase)
};

// Fundamental of a function over one period [t0, t0 + T], by quadrature.
template <class F>
Fundamental FundamentalOf(F&& f, double t0, double period) {
  const int n = 4000;
  double a = 0, b = 0;
  for (int i = 0; i < n; ++i) {
    const double t = t0 + period * i / n, w = 2 * kPi / period;
    a += f(t) * std::sin(w * t) * 2.0 / n;
    b += f(t) * std::cos(w * t) * 2.0 / n;
  }
  return {std::hypot(a, b), std::atan2(b, a)};
}

// Runs the loop over `periods` periods after settling; returns the last period's trajectory.
StrokeTrajectory RunSine(const ServoActuator& actuator, const SineSetPoint& set, const PeriodicLoad& load,
                         ActuatorStats* stats = nullptr) {
  const double period = 1.0 / set.frequency;
  ServoActuator::State state = actuator.SettledState(set, load, 0.0, 2 * period);
  return actuator.Run(set, load, 0.0, period, state, stats);
}

TEST(SimActuator, TracksAShakerSineWithAPhaseLagOfAboutOneDegree) {
  const ServoActuator actuator({});
  const SineSetPoint set{2.0, 0.133, 0.010, 0.0};
  const StrokeTrajectory y = RunSine(actuator, set, PeriodicLoad::Constant(6000.0));
  const Fundamental f = FundamentalOf([&](double t) { return y.At(t).value - set.mean; }, 0.0, 0.5);
  const double lag_deg = -f.phase * 180 / kPi;
  EXPECT_GT(lag_deg, 0.3);
  EXPECT_LT(lag_deg, 3.0);  // damper-physics.md §2.11: 1-3 degrees at 2 Hz
  EXPECT_NEAR(f.amplitude / set.amplitude, 1.0, 0.01);

  // Without feed-forward the loop is a first-order lag: atan(f / f_loop) = 7.6 degrees at no load.
  ActuatorOptions plain;
  plain.feedforward = 0.0;
  const StrokeTrajectory z = RunSine(ServoActuator(plain), set, PeriodicLoad::Constant(0.0));
  const double plain_lag = -FundamentalOf([&](double t) { return z.At(t).value - set.mean; }, 0.0, 0.5).phase * 180 / kPi;
  EXPECT_NEAR(plain_lag, std::atan(2.0 / 15.0) * 180 / kPi, 1.5);
}

TEST(SimActuator, LargeFastStrokesSaturateAtTheFlowLimit) {
  const ServoActuator actuator({});
  const SineSetPoint set{2.0, 0.133, 0.060, 0.0};  // needs 0.75 m/s, the valve gives 0.4
  ActuatorStats stats;
  const StrokeTrajectory y = RunSine(actuator, set, PeriodicLoad::Constant(6000.0), &stats);
  double peak_rate = 0, lo = 1, hi = -1;
  for (int i = 0; i <= 1000; ++i) {
    const InputSample s = y.At(0.5 * i / 1000);
    peak_rate = std::max(peak_rate, std::abs(s.rate));
    lo = std::min(lo, s.value), hi = std::max(hi, s.value);
  }
  EXPECT_LE(peak_rate, 0.4 * std::sqrt(1.0 + 6000.0 / 50e3) * 1.01);  // the load helps extension
  EXPECT_LT(0.5 * (hi - lo), 0.8 * set.amplitude);  // the stroke falls short
  EXPECT_GT(stats.saturated_fraction, 0.2);
  EXPECT_GT(stats.max_tracking_error, 0.01);
}

TEST(SimActuator, StallsAgainstALoadAtItsForceLimit) {
  const ServoActuator actuator({});
  const SineSetPoint set{1.0, 0.200, 0.020, 0.0};  // needs 0.126 m/s
  const auto compression_rate = [&](double load) {
    const StrokeTrajectory y = RunSine(actuator, set, PeriodicLoad::Constant(load));
    double peak = 0;
    for (int i = 0; i <= 1000; ++i) peak = std::max(peak, y.At(1.0 * i / 1000).rate);
    return peak;
  };
  EXPECT_GT(compression_rate(10e3), 0.12);
  EXPECT_LT(compression_rate(49.5e3), 0.4 * std::sqrt(0.01) * 1.5);  // sqrt(1 - F / F_stall) of the flow
  EXPECT_LT(compression_rate(60e3), 0.005);                          // beyond the stall force: no compression
  ActuatorStats stats;
  RunSine(actuator, set, PeriodicLoad::Constant(49.5e3), &stats);
  EXPECT_NEAR(stats.max_load_fraction, 0.99, 1e-9);
  EXPECT_GT(stats.max_tracking_error, 0.01);
}

TEST(SimActuator, IdealActuatorFollowsTheSetPointExactly) {
  ActuatorOptions o;
  o.ideal = true;
  const SineSetPoint set{0.5, 0.1, 0.03, 0.7};
  ServoActuator::State state = ServoActuator(o).SettledState(set, PeriodicLoad::Constant(0), 0.0, 1.0);
  const StrokeTrajectory y = ServoActuator(o).Run(set, PeriodicLoad::Constant(0), 0.0, 2.0, state);
  for (double t : {0.0, 0.3337, 1.9}) {
    EXPECT_NEAR(y.At(t).value, set.At(t).value, 1e-12);
    EXPECT_NEAR(y.At(t).rate, set.At(t).rate, 1e-6);
  }
}

TEST(SimActuator, StrokeSignalsHaveConsistentDerivatives) {
  const ServoActuator actuator({});
  const SineSetPoint set{1.0, 0.133, 0.021, 0.3};
  const StrokeTrajectory y = RunSine(actuator, set, PeriodicLoad::Constant(6000.0));
  // Quintic Hermite: rates are the derivatives of the values, between and at knots.
  for (double t : {0.1234567, 0.5, 0.77777}) {
    const double h = 1e-6;
    EXPECT_NEAR((y.At(t + h).value - y.At(t - h).value) / (2 * h), y.At(t).rate, 1e-6);
    EXPECT_NEAR((y.At(t + h).rate - y.At(t - h).rate) / (2 * h), y.At(t).accel, 1e-3);
  }
  // The Fourier series through the knots, with the end mismatch carried by the trend.
  const int n = 2000;
  std::vector<double> samples(n);
  for (int j = 0; j < n; ++j) samples[j] = y.At(1.0 * j / n).value + 1e-4 * j / n;  // does not repeat
  const InputSample first = y.At(0.0), last = y.At(1.0);
  const FourierSignal series = FourierSignal::Fit(samples, 1.0, 0.0, 1e-10, 1000,
                                                  {last.value + 1e-4 - first.value, last.rate - first.rate,
                                                   last.accel - first.accel});
  EXPECT_LT(series.harmonics(), 200);
  for (double t : {0.0, 0.25, 0.6123, 0.999}) {
    EXPECT_NEAR(series.At(t).value, y.At(t).value + 1e-4 * t, 1e-8) << t;
    EXPECT_NEAR(series.At(t).rate, y.At(t).rate + 1e-4, 1e-5) << t;
  }
  const double h = 1e-6;
  EXPECT_NEAR((series.At(0.4 + h).rate - series.At(0.4 - h).rate) / (2 * h), series.At(0.4).accel, 1e-4);
}

TEST(SimActuator, InvalidSettingsAreRejectedWithTheReason) {
  std::string error;
  ActuatorOptions o;
  o.valve_bandwidth = 10.0;  // below the loop
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_NE(error.find("valve_bandwidth"), std::string::npos);
  o = {};
  o.control_rate = 500.0;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_THROW(ServoActuator{o}, std::invalid_argument);
  o = {};
  o.stall_force = -1;
  EXPECT_FALSE(o.IsValid(&error));
}

}  // namespace
}  // namespace strut::sim
