#include "strut/sim/actuator.h"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <unsupported/Eigen/FFT>

namespace strut::sim {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;
// Smoothing of the valve law: width of the flow-direction switch (spool fraction) and of the
// stall floor (fraction of the supply pressure). Small enough to leave the physics alone, large
// enough that y'' stays continuous for IDA.
constexpr double kDirectionWidth = 0.02;
constexpr double kStallWidth = 1e-3;

//! Smooth saturation to -1..1, linear to 4e-4 relative below |u| = 0.5.
double Saturate(double u) { return u / std::pow(1.0 + std::pow(u, 8), 0.125); }

//! sqrt(softplus) and its derivative: a square root with a smooth floor at zero.
struct Root {
  double value, slope;
};
Root SmoothRoot(double z) {
  const double a = z / kStallWidth;
  const double softplus = kStallWidth * (a > 0 ? a + std::log1p(std::exp(-a)) : std::log1p(std::exp(a)));
  const double sigmoid = a > 0 ? 1.0 / (1.0 + std::exp(-a)) : std::exp(a) / (1.0 + std::exp(a));
  const double value = std::sqrt(softplus);
  return {value, sigmoid / (2.0 * value)};
}

}  // namespace

bool ActuatorOptions::IsValid(std::string* error) const {
  const auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  const auto positive = [](double v) { return std::isfinite(v) && v > 0; };
  if (ideal) return true;
  if (!positive(loop_bandwidth)) return fail(fmt::format("loop_bandwidth must be positive, got {} Hz", loop_bandwidth));
  if (!std::isfinite(feedforward) || feedforward < 0 || feedforward > 1.2)
    return fail(fmt::format("feedforward must be 0..1.2, got {}", feedforward));
  if (!positive(valve_bandwidth) || valve_bandwidth <= loop_bandwidth)
    return fail(fmt::format("valve_bandwidth must exceed loop_bandwidth ({} Hz), got {} Hz", loop_bandwidth,
                            valve_bandwidth));
  if (!positive(max_velocity)) return fail(fmt::format("max_velocity must be positive, got {} m/s", max_velocity));
  if (!positive(stall_force)) return fail(fmt::format("stall_force must be positive, got {} N", stall_force));
  if (!std::isfinite(force_limit) || force_limit < 0)
    return fail(fmt::format("force_limit must be 0 (off) or positive, got {} N", force_limit));
  if (!positive(control_rate) || control_rate < 20.0 * valve_bandwidth)
    return fail(fmt::format("control_rate must be at least 20 times valve_bandwidth ({} Hz) for the RK4 loop, got {} Hz",
                            20.0 * valve_bandwidth, control_rate));
  return true;
}

InputSample SineSetPoint::At(double t) const {
  const double w = kTwoPi * frequency;
  const double s = std::sin(w * t + phase), c = std::cos(w * t + phase);
  return {mean + amplitude * s, amplitude * w * c, -amplitude * w * w * s};
}

// ---------------------------------------------------------------------------------------------

PeriodicLoad PeriodicLoad::FromGrid(std::span<const double> values, double period) {
  const int n = static_cast<int>(values.size());
  if (n < 4 || !(period > 0)) throw std::invalid_argument("periodic load: needs at least 4 grid values and a period");
  PeriodicLoad load;
  load.period_ = period;
  const double h = period / n;
  load.values_.assign(values.begin(), values.end());
  load.values_.push_back(values[0]);
  load.rates_.resize(n + 1);
  const auto v = [&](int k) { return values[((k % n) + n) % n]; };
  for (int k = 0; k < n; ++k) load.rates_[k] = (v(k - 2) - 8.0 * v(k - 1) + 8.0 * v(k + 1) - v(k + 2)) / (12.0 * h);
  load.rates_[n] = load.rates_[0];
  return load;
}

PeriodicLoad PeriodicLoad::FromSamples(std::span<const double> values, std::span<const double> rates, double period) {
  if (values.size() < 2 || rates.size() != values.size() || !(period > 0))
    throw std::invalid_argument("periodic load: needs n + 1 values and rates and a period");
  PeriodicLoad load;
  load.period_ = period;
  load.values_.assign(values.begin(), values.end());
  load.rates_.assign(rates.begin(), rates.end());
  return load;
}

PeriodicLoad PeriodicLoad::Constant(double force) {
  PeriodicLoad load;
  load.values_ = {force, force};
  load.rates_ = {0.0, 0.0};
  return load;
}

InputSample PeriodicLoad::At(double t) const {
  const int n = static_cast<int>(values_.size()) - 1;
  double phase = std::fmod(t, period_);
  if (phase < 0) phase += period_;
  const double h = period_ / n;
  const int k = std::min(n - 1, static_cast<int>(phase / h));
  const double s = phase / h - k;
  // Cubic Hermite on [k, k + 1].
  const double p0 = values_[k], p1 = values_[k + 1], m0 = rates_[k] * h, m1 = rates_[k + 1] * h;
  const double s2 = s * s, s3 = s2 * s;
  const double value = (2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * m0 + (-2 * s3 + 3 * s2) * p1 + (s3 - s2) * m1;
  const double ds = (6 * s2 - 6 * s) * p0 + (3 * s2 - 4 * s + 1) * m0 + (-6 * s2 + 6 * s) * p1 + (3 * s2 - 2 * s) * m1;
  return {value, ds / h, 0.0};
}

// ---------------------------------------------------------------------------------------------

StrokeTrajectory::StrokeTrajectory(double start, double step, std::vector<double> y, std::vector<double> rate,
                                   std::vector<double> accel)
    : start_(start), step_(step), y_(std::move(y)), rate_(std::move(rate)), accel_(std::move(accel)) {
  if (y_.size() < 2 || rate_.size() != y_.size() || accel_.size() != y_.size() || !(step_ > 0))
    throw std::invalid_argument("stroke trajectory: needs at least two knots with rates and a positive step");
}

InputSample StrokeTrajectory::At(double t) const {
  const int last = static_cast<int>(y_.size()) - 1;
  const double x = std::clamp((t - start_) / step_, 0.0, static_cast<double>(last));
  const int k = std::min(last - 1, static_cast<int>(x));
  const double s = x - k, h = step_;
  // Quintic Hermite through (y, y', y'') at both knots.
  const double p0 = y_[k], p1 = y_[k + 1];
  const double v0 = rate_[k] * h, v1 = rate_[k + 1] * h;
  const double a0 = accel_[k] * h * h, a1 = accel_[k + 1] * h * h;
  const double d = p1 - p0;
  const double c0 = p0, c1 = v0, c2 = 0.5 * a0;
  const double c3 = 10 * d - 6 * v0 - 4 * v1 - 1.5 * a0 + 0.5 * a1;
  const double c4 = -15 * d + 8 * v0 + 7 * v1 + 1.5 * a0 - a1;
  const double c5 = 6 * d - 3 * v0 - 3 * v1 - 0.5 * a0 + 0.5 * a1;
  const double value = c0 + s * (c1 + s * (c2 + s * (c3 + s * (c4 + s * c5))));
  const double ds = c1 + s * (2 * c2 + s * (3 * c3 + s * (4 * c4 + s * 5 * c5)));
  const double dss = 2 * c2 + s * (6 * c3 + s * (12 * c4 + s * 20 * c5));
  return {value, ds / h, dss / (h * h)};
}

// ---------------------------------------------------------------------------------------------

FourierSignal FourierSignal::Fit(std::span<const double> samples, double period, double start, double floor,
                                 int max_harmonics, const InputSample& end_mismatch) {
  const int n = static_cast<int>(samples.size());
  if (n < 4 || !(period > 0) || max_harmonics < 1)
    throw std::invalid_argument("Fourier signal: needs at least 4 samples, a period and a harmonic");
  FourierSignal s;
  s.start_ = start;
  s.period_ = period;
  s.omega_ = kTwoPi / period;
  // Quintic p(s) with p = p' = p'' = 0 at s = 0 and the mismatch at s = 1 (in units of s).
  const double d0 = end_mismatch.value, d1 = end_mismatch.rate * period, d2 = end_mismatch.accel * period * period;
  s.c3_ = 10 * d0 - 4 * d1 + 0.5 * d2;
  s.c4_ = -15 * d0 + 7 * d1 - d2;
  s.c5_ = 6 * d0 - 3 * d1 + 0.5 * d2;
  std::vector<double> in(samples.begin(), samples.end());
  for (int j = 0; j < n; ++j) in[j] -= s.Trend(start + period * j / n).value;
  Eigen::FFT<double> fft;
  std::vector<std::complex<double>> spectrum;
  fft.fwd(spectrum, in);
  const int kmax = std::min(max_harmonics, (n - 1) / 2);  // no Nyquist term: it has no derivative
  s.a_.assign(kmax + 1, 0.0);
  s.b_.assign(kmax + 1, 0.0);
  s.a_[0] = spectrum[0].real() / n;
  int last = 0;
  for (int k = 1; k <= kmax; ++k) {
    // x_j = sum_k c_k e^{2 pi i k j / n}: a_k = 2 Re(X_k) / n, b_k = -2 Im(X_k) / n.
    s.a_[k] = 2.0 * spectrum[k].real() / n;
    s.b_[k] = -2.0 * spectrum[k].imag() / n;
    if (std::hypot(s.a_[k], s.b_[k]) > floor) last = k;
  }
  s.a_.resize(last + 1);
  s.b_.resize(last + 1);
  return s;
}

InputSample FourierSignal::Trend(double t) const {
  const double x = (t - start_) / period_;
  const double value = x * x * x * (c3_ + x * (c4_ + x * c5_));
  const double ds = x * x * (3 * c3_ + x * (4 * c4_ + x * 5 * c5_));
  const double dss = x * (6 * c3_ + x * (12 * c4_ + x * 20 * c5_));
  return {value, ds / period_, dss / (period_ * period_)};
}

InputSample FourierSignal::At(double t) const {
  const double w = omega_, phase = w * (t - start_);
  const double c1 = std::cos(phase), s1 = std::sin(phase);
  double ck = 1.0, sk = 0.0;
  InputSample out = Trend(t);
  out.value += a_[0];
  for (std::size_t k = 1; k < a_.size(); ++k) {
    const double c = ck * c1 - sk * s1;
    sk = sk * c1 + ck * s1;
    ck = c;
    const double kw = static_cast<double>(k) * w;
    out.value += a_[k] * ck + b_[k] * sk;
    out.rate += kw * (b_[k] * ck - a_[k] * sk);
    out.accel -= kw * kw * (a_[k] * ck + b_[k] * sk);
  }
  return out;
}

// ---------------------------------------------------------------------------------------------

namespace {
//! Coefficients of the derivative of a Chebyshev series (in x), the usual backward recurrence.
std::vector<double> ChebyshevDerivative(const std::vector<double>& c) {
  const int n = static_cast<int>(c.size()) - 1;
  std::vector<double> d(std::max(1, n), 0.0);
  if (n == 0) return d;
  for (int k = n - 1; k >= 0; --k) d[k] = (k + 2 <= n - 1 ? d[k + 2] : 0.0) + 2.0 * (k + 1) * c[k + 1];
  d[0] *= 0.5;
  return d;
}

//! Sum c_k T_k(x) by Clenshaw's recurrence.
double Clenshaw(const std::vector<double>& c, double x) {
  double b1 = 0.0, b2 = 0.0;
  for (int k = static_cast<int>(c.size()) - 1; k >= 1; --k) {
    const double b0 = 2.0 * x * b1 - b2 + c[k];
    b2 = b1;
    b1 = b0;
  }
  return x * b1 - b2 + c[0];
}
}  // namespace

ChebyshevSignal ChebyshevSignal::Fit(const std::function<double(double)>& f, double start, double end, int degree) {
  if (!(end > start) || !std::isfinite(start) || !std::isfinite(end) || degree < 1 || degree > 256)
    throw std::invalid_argument(
        fmt::format("Chebyshev signal: needs start < end and a degree 1..256, got [{}, {}] and {}", start, end, degree));
  ChebyshevSignal s;
  s.start_ = start;
  s.end_ = end;
  const int n = degree + 1;
  std::vector<double> values(n);
  for (int j = 0; j < n; ++j) {
    const double x = std::cos(std::numbers::pi * (j + 0.5) / n);
    values[j] = f(0.5 * (start + end) + 0.5 * (end - start) * x);
    if (!std::isfinite(values[j]))
      throw std::invalid_argument(fmt::format("Chebyshev signal: the function is not finite at node {}", j));
  }
  // c_k = 2/n sum_j f(x_j) cos(pi k (j + 1/2) / n); c_0 halved.
  s.c_.assign(n, 0.0);
  for (int k = 0; k < n; ++k) {
    double sum = 0.0;
    for (int j = 0; j < n; ++j) sum += values[j] * std::cos(std::numbers::pi * k * (j + 0.5) / n);
    s.c_[k] = (k == 0 ? 1.0 : 2.0) * sum / n;
  }
  s.d1_ = ChebyshevDerivative(s.c_);
  s.d2_ = ChebyshevDerivative(s.d1_);
  return s;
}

InputSample ChebyshevSignal::At(double t) const {
  const double scale = 2.0 / (end_ - start_);
  const double x = (2.0 * t - start_ - end_) / (end_ - start_);
  return {Clenshaw(c_, x), Clenshaw(d1_, x) * scale, Clenshaw(d2_, x) * scale * scale};
}

// ---------------------------------------------------------------------------------------------

void ActuatorStats::Merge(const ActuatorStats& other) {
  max_tracking_error = std::max(max_tracking_error, other.max_tracking_error);
  max_valve_opening = std::max(max_valve_opening, other.max_valve_opening);
  saturated_fraction = std::max(saturated_fraction, other.saturated_fraction);
  max_load_fraction = std::max(max_load_fraction, other.max_load_fraction);
}

ServoActuator::ServoActuator(ActuatorOptions options) : options_(options) {
  std::string error;
  if (!options_.IsValid(&error)) throw std::invalid_argument("actuator: " + error);
  kv_ = kTwoPi * options_.loop_bandwidth;
  wv_ = kTwoPi * options_.valve_bandwidth;
}

void ServoActuator::Rates(const State& s, const InputSample& r, const InputSample& load, double* y_rate,
                          double* spool_rate, double* y_accel) const {
  const double u = (kv_ * (r.value - s.stroke) + options_.feedforward * r.rate) / options_.max_velocity;
  ValveRates(s, Saturate(u), load, y_rate, spool_rate, y_accel);
}

void ServoActuator::ValveRates(const State& s, double spool_target, const InputSample& load, double* y_rate,
                               double* spool_rate, double* y_accel) const {
  const ActuatorOptions& o = options_;
  const double xd = wv_ * (spool_target - s.spool);
  // Valve flow factor: the load pressure opposes flow into the loaded chamber (x > 0 compresses
  // the damper against a compression-positive load) and helps the other way.
  const double f = load.value / o.stall_force, fd = load.rate / o.stall_force;
  const Root against = SmoothRoot(1.0 - f), with = SmoothRoot(1.0 + f);
  const double th = std::tanh(s.spool / kDirectionWidth);
  const double h = 0.5 * (1.0 + th), hx = 0.5 * (1.0 - th * th) / kDirectionWidth;
  const double g = h * against.value + (1.0 - h) * with.value;
  const double gx = hx * (against.value - with.value);
  const double gf = -h * against.slope + (1.0 - h) * with.slope;
  *y_rate = o.max_velocity * s.spool * g;
  *spool_rate = xd;
  *y_accel = o.max_velocity * (xd * g + s.spool * (gx * xd + gf * fd));
}

ServoActuator::State ServoActuator::SettledState(const SineSetPoint& set_point, const PeriodicLoad& load, double t0,
                                                 double settle) const {
  const InputSample r = set_point.At(t0 - settle);
  State state{r.value, 0.0};
  if (options_.ideal) return {set_point.At(t0).value, 0.0};
  Run(set_point, load, t0 - settle, settle, state);
  return state;
}

StrokeTrajectory ServoActuator::Run(const SineSetPoint& set_point, const PeriodicLoad& load, double t0,
                                    double duration, State& state, ActuatorStats* stats) const {
  return Run([&set_point](double t) { return set_point.At(t); }, [&load](double t) { return load.At(t); }, t0,
             duration, state, stats);
}

StrokeTrajectory ServoActuator::Run(const Signal& command, const Signal& load, double t0, double duration,
                                    State& state, ActuatorStats* stats, double valve_closed_from) const {
  const double h = 1.0 / options_.control_rate;
  const long steps = std::max<long>(1, std::lround(duration / h));
  const double step = duration / steps > 0 ? duration / steps : h;
  // The first knot at or after valve_closed_from: the loop is open from there on.
  const double closed_knot = std::ceil((valve_closed_from - t0) / step - 1e-9);
  const auto closed = [&](long k) { return static_cast<double>(k) >= closed_knot; };
  std::vector<double> y(steps + 1), yd(steps + 1), ydd(steps + 1);
  if (options_.ideal) {
    // Without a loop the stroke is the command; a closed valve holds it where it was.
    std::optional<InputSample> held;
    for (long k = 0; k <= steps; ++k) {
      InputSample r = command(t0 + k * step);
      if (closed(k)) {
        if (!held) held = InputSample{k == 0 ? state.stroke : y[k - 1], 0.0, 0.0};
        r = *held;
      }
      y[k] = r.value, yd[k] = r.rate, ydd[k] = r.accel;
    }
    state.stroke = y.back();
    return StrokeTrajectory(t0, step, std::move(y), std::move(yd), std::move(ydd));
  }
  ActuatorStats local;
  long saturated = 0;
  // Rates on step k's interval with its load f: the loop closed on the command r, or the valve closing.
  const auto rates = [&](long k, const State& s, const InputSample& r, const InputSample& f, double* v,
                              double* xd, double* a) {
    if (closed(k))
      ValveRates(s, 0.0, f, v, xd, a);
    else
      Rates(s, r, f, v, xd, a);
  };
  const auto record = [&](long k, double t, const State& s) {
    const InputSample r = closed(k) ? InputSample{} : command(t), f = load(t);  // each evaluated once
    double xd = 0.0;
    rates(k, s, r, f, &yd[k], &xd, &ydd[k]);
    y[k] = s.stroke;
    if (!closed(k)) local.max_tracking_error = std::max(local.max_tracking_error, std::abs(r.value - s.stroke));
    local.max_valve_opening = std::max(local.max_valve_opening, std::abs(s.spool));
    local.max_load_fraction = std::max(local.max_load_fraction, std::abs(f.value) / options_.stall_force);
    if (std::abs(s.spool) > 0.95) ++saturated;
  };
  const auto derivative = [&](long k, double t, const State& s) {
    double v = 0.0, xd = 0.0, a = 0.0;
    // A closed valve needs no command.
    rates(k, s, closed(k) ? InputSample{} : command(t), load(t), &v, &xd, &a);
    return State{v, xd};
  };
  State s = state;
  record(0, t0, s);
  for (long k = 0; k < steps; ++k) {
    const double t = t0 + k * step;
    const State k1 = derivative(k, t, s);
    const State k2 = derivative(k, t + 0.5 * step, {s.stroke + 0.5 * step * k1.stroke, s.spool + 0.5 * step * k1.spool});
    const State k3 = derivative(k, t + 0.5 * step, {s.stroke + 0.5 * step * k2.stroke, s.spool + 0.5 * step * k2.spool});
    const State k4 = derivative(k, t + step, {s.stroke + step * k3.stroke, s.spool + step * k3.spool});
    s.stroke += step / 6.0 * (k1.stroke + 2 * k2.stroke + 2 * k3.stroke + k4.stroke);
    s.spool += step / 6.0 * (k1.spool + 2 * k2.spool + 2 * k3.spool + k4.spool);
    record(k + 1, t0 + (k + 1) * step, s);
  }
  state = s;
  local.saturated_fraction = static_cast<double>(saturated) / (steps + 1);
  if (stats) stats->Merge(local);
  return StrokeTrajectory(t0, step, std::move(y), std::move(yd), std::move(ydd));
}

}  // namespace strut::sim
