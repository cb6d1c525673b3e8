// The servo-hydraulic actuator of the simulated rig in stroke control: a stroke set-point goes in,
// the actual stroke comes out, with finite loop bandwidth, tracking error, a flow (velocity) limit
// and a force (supply-pressure) limit. docs/simulated-rig.md gives the equations and defaults.
//
// Model (per unit of the LVDT reading y, m; spool opening x normalised to -1..1):
//   u   = (Kv (r - y) + kff r') / v_max            position loop with velocity feed-forward
//   x'  = wv (sat(u) - x)                          first-order servo valve, smooth saturation
//   y'  = v_max x g(F, x)                          flow through the valve moves the piston
//   g   = sqrt(1 - F / F_stall) when x pushes against the load F, sqrt(1 + F / F_stall) when the
//         load helps (the classic valve equation with load pressure F / A and supply pressure
//         F_stall / A), smoothed so that the stroke stays twice differentiable.
// The damper sees the actual stroke (stroke-input causality); the load is the axle force.
#pragma once

#include <cmath>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "strut/sim/transient.h"

namespace strut::sim {

//! Settings of the stroke-control loop and the hydraulics. Defaults: a 50 kN, 0.4 m/s lab actuator
//! with a 15 Hz position loop (damper-physics.md §2.11: 1-3 degrees of phase lag at 2 Hz).
struct ActuatorOptions {
  //! The stroke follows the set-point exactly (no loop, no limits): for checks against the
  //! periodic solver and for idealised datasets.
  bool ideal = false;
  //! Position-loop bandwidth, Hz: loop gain Kv = 2 pi loop_bandwidth (1/s). 10-20 Hz is typical of
  //! a shaker rig; lower gives more tracking error.
  double loop_bandwidth = 15.0;
  //! Velocity feed-forward as a fraction of the set-point rate, 0..1.2. 0.9 leaves a phase lag of
  //! about 1 degree at 2 Hz; 0 gives the pure first-order lag atan(f / loop_bandwidth).
  double feedforward = 0.9;
  //! Servo-valve bandwidth (first-order spool dynamics), Hz. Must exceed loop_bandwidth.
  double valve_bandwidth = 100.0;
  //! No-load piston velocity at full valve opening, m/s: rated flow over piston area (flow limit).
  //! Strokes that need more saturate (triangular stroke, reduced amplitude).
  double max_velocity = 0.4;
  //! Force at which the piston stalls, N: supply pressure times piston area (force limit).
  double stall_force = 5.0e4;
  //! Force-limit interlock, N (0: none): when the load cell reads more than this in magnitude the
  //! controller stops the test (MTS-style limit detector with an interlock action) and the
  //! experiment is recorded as aborted. Below the stall force, so the loop never runs stalled.
  double force_limit = 4.5e4;
  //! Rate at which the loop is integrated and the stroke is stored (classic RK4), Hz.
  double control_rate = 2000.0;
  bool IsValid(std::string* error) const;
};

//! Sinusoidal stroke set-point r(t) = mean + amplitude sin(2 pi f t + phase) (LVDT reading, m).
struct SineSetPoint {
  double frequency = 1.0;
  double mean = 0.0;
  double amplitude = 0.0;
  double phase = 0.0;  //!< rad
  InputSample At(double t) const;
};

//! A periodic force history (the load on the actuator) with a continuous rate: cubic Hermite
//! between equidistant samples that cover one period.
class PeriodicLoad {
 public:
  PeriodicLoad() = default;
  //! n values at t = k T / n (k = 0..n-1); rates from fourth-order periodic central differences.
  static PeriodicLoad FromGrid(std::span<const double> values, double period);
  //! n + 1 values and rates at t = k T / n (k = 0..n, the last one closes the period).
  static PeriodicLoad FromSamples(std::span<const double> values, std::span<const double> rates, double period);
  //! A constant force.
  static PeriodicLoad Constant(double force);
  InputSample At(double t) const;  //!< value and rate (accel not set)

 private:
  double period_ = 1.0;
  std::vector<double> values_, rates_;  //!< values_.size() = n + 1 (closing sample included)
};

//! The actual stroke of one stretch of time: the LVDT reading y with its rates on knots every
//! 1 / control_rate, interpolated by quintic Hermite polynomials (continuous y, y', y'').
class StrokeTrajectory {
 public:
  StrokeTrajectory() = default;
  StrokeTrajectory(double start, double step, std::vector<double> y, std::vector<double> rate,
                   std::vector<double> accel);
  //! y, y', y'' at absolute time t, start() <= t <= end() (clamped to the ends).
  InputSample At(double t) const;
  double start() const { return start_; }
  double end() const { return start_ + step_ * static_cast<double>(y_.size() - 1); }
  std::size_t knots() const { return y_.size(); }

 private:
  double start_ = 0.0, step_ = 1.0;
  std::vector<double> y_, rate_, accel_;
};

//! A smooth periodic signal: the truncated Fourier series of equidistant samples over one period.
//! The damper integrator gets the actual stroke this way: infinitely differentiable, so IDA's
//! high-order steps are not cut short by the knots of a piecewise interpolant.
class FourierSignal {
 public:
  FourierSignal() = default;
  //! Samples at start + k period / n, k = 0..n-1. The series is periodic; a signal that does not
  //! quite repeat (settling) gives `end_mismatch`: value, rate and acceleration at start + period
  //! minus those at start. A quintic that carries the mismatch is taken out before the fit and
  //! added back, so the rest is periodic with two continuous derivatives and needs few harmonics.
  //! Keeps the harmonics up to the last one whose amplitude exceeds `floor`, at most
  //! `max_harmonics`. Throws std::invalid_argument on bad sizes.
  static FourierSignal Fit(std::span<const double> samples, double period, double start, double floor,
                           int max_harmonics, const InputSample& end_mismatch = {});
  InputSample At(double t) const;
  int harmonics() const { return static_cast<int>(a_.size()) - 1; }

 private:
  InputSample Trend(double t) const;
  double start_ = 0.0, period_ = 1.0, omega_ = 0.0;
  std::vector<double> a_, b_;
  double c3_ = 0.0, c4_ = 0.0, c5_ = 0.0;  //!< trend c3 s^3 + c4 s^4 + c5 s^5, s = (t - start) / period
};

//! A smooth signal on one stretch [start, end]: the Chebyshev interpolant of a function at the
//! Chebyshev points of that stretch, with exact derivatives of the polynomial. The simulated
//! controller hands the actual stroke of each chunk to the damper this way: a polynomial has no
//! knots and, unlike a Fourier series of a stretch that does not repeat, no ringing at the ends.
class ChebyshevSignal {
 public:
  ChebyshevSignal() = default;
  //! The interpolant of degree `degree` (1..256) through f at the Chebyshev points of the first
  //! kind. Throws std::invalid_argument for an empty stretch, a bad degree or a non-finite value.
  static ChebyshevSignal Fit(const std::function<double(double)>& f, double start, double end, int degree);
  //! Value, rate and acceleration at t (extrapolates outside [start, end]).
  InputSample At(double t) const;
  int degree() const { return static_cast<int>(c_.size()) - 1; }

 private:
  double start_ = 0.0, end_ = 1.0;
  std::vector<double> c_, d1_, d2_;  //!< coefficients of the value, its first and second derivative (in x)
};

//! What the limit detectors saw over a run (an MTS-style "indicate").
struct ActuatorStats {
  double max_tracking_error = 0.0;  //!< max |r - y|, m
  double max_valve_opening = 0.0;   //!< max |x|, 0..1
  double saturated_fraction = 0.0;  //!< fraction of time with |x| > 0.95 (flow limit)
  double max_load_fraction = 0.0;   //!< max |F| / stall_force (force limit at 1)
  void Merge(const ActuatorStats& other);
};

//! Integrates the stroke-control loop; pure logic, the caller keeps the state between runs.
class ServoActuator {
 public:
  struct State {
    double stroke = 0.0;  //!< y, LVDT reading, m
    double spool = 0.0;   //!< x, -1..1
  };

  //! Throws std::invalid_argument when the options are not valid.
  explicit ServoActuator(ActuatorOptions options);
  const ActuatorOptions& options() const { return options_; }

  //! A state at time t0 that has forgotten its start: the loop run over `settle` seconds before t0
  //! from rest at the set-point.
  State SettledState(const SineSetPoint& set_point, const PeriodicLoad& load, double t0, double settle) const;

  //! Integrates over [t0, t0 + duration] from `state` (updated to the end state) and returns the
  //! stroke on knots; `stats` (optional) accumulates the limit detectors. The ideal actuator returns
  //! the set-point itself. Duration is rounded to whole control steps (at least one).
  StrokeTrajectory Run(const SineSetPoint& set_point, const PeriodicLoad& load, double t0, double duration,
                       State& state, ActuatorStats* stats = nullptr) const;

  //! A signal of absolute time: value and rate (the loop uses no acceleration).
  using Signal = std::function<InputSample(double t)>;
  //! As above for any command r(t) and load F(t) (the simulated controller's ramps and sines).
  //! From `valve_closed_from` on (rounded up to a control step) the hydraulics are off: the spool
  //! closes at the valve bandwidth whatever the command, and the locked oil holds the piston where
  //! it stops (the ideal actuator holds the command's value at that time).
  StrokeTrajectory Run(const Signal& command, const Signal& load, double t0, double duration, State& state,
                       ActuatorStats* stats = nullptr, double valve_closed_from = INFINITY) const;

  //! y' and y'' for a state, set-point sample and load sample (exposed for tests).
  void Rates(const State& s, const InputSample& r, const InputSample& load, double* y_rate, double* spool_rate,
             double* y_accel) const;

 private:
  //! y' and y'' with the spool driven towards `spool_target` (sat(u) with the loop closed, 0 with
  //! the valve closed).
  void ValveRates(const State& s, double spool_target, const InputSample& load, double* y_rate, double* spool_rate,
                  double* y_accel) const;
  ActuatorOptions options_;
  double kv_ = 0.0, wv_ = 0.0;
};

}  // namespace strut::sim
