#include "strut/sim/transient.h"

#include "ida_run.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fmt/format.h>
#include <limits>
#include <numbers>
#include <spdlog/spdlog.h>
#include <type_traits>

namespace strut::sim {

using ident::Causality;
using ident::Jet;
using ident::Model;

// ---------------------------------------------------------------------------------------------
// Inputs

InputSignal::InputSignal(Function f) : f_(std::move(f)) {}

InputSignal InputSignal::Constant(double value) {
  return InputSignal([value](double) { return InputSample{value, 0.0, 0.0}; });
}

InputSignal InputSignal::Sine(double frequency, double mean, double amplitude) {
  const double w = 2.0 * std::numbers::pi * frequency;
  return InputSignal([=](double t) {
    const double s = std::sin(w * t), c = std::cos(w * t);
    return InputSample{mean + amplitude * s, amplitude * w * c, -amplitude * w * w * s};
  });
}

InputSignal InputSignal::FromPeriodic(const ident::PeriodicInput& input) {
  const int n = static_cast<int>(input.values.size());
  if (n < 1 || !(input.frequency > 0) || !std::isfinite(input.frequency))
    throw std::invalid_argument("periodic input: needs grid values and a positive frequency");
  for (double v : input.values)
    if (!std::isfinite(v)) throw std::invalid_argument("periodic input: the grid has non-finite values");
  // u(t) = a0 + sum_k a_k cos(k w t) + b_k sin(k w t), k = 1..n/2: the real DFT of the grid.
  // Twiddles use (k mu mod n) so that large n keeps full accuracy.
  const int kmax = n / 2;
  std::vector<double> a(kmax + 1, 0.0), b(kmax + 1, 0.0);
  for (int k = 0; k <= kmax; ++k) {
    double sc = 0.0, ss = 0.0;
    for (int mu = 0; mu < n; ++mu) {
      const double angle = 2.0 * std::numbers::pi * static_cast<double>((static_cast<long>(k) * mu) % n) / n;
      sc += input.values[mu] * std::cos(angle);
      ss += input.values[mu] * std::sin(angle);
    }
    const bool single = k == 0 || (n % 2 == 0 && k == kmax);  // the mean and the real Nyquist term
    a[k] = (single ? 1.0 : 2.0) * sc / n;
    b[k] = single ? 0.0 : 2.0 * ss / n;
  }
  // Trailing harmonics at rounding level are dropped: a band-limited input sampled on a fine grid
  // (a sine on 1600 points) then costs a few harmonics per call instead of n / 2.
  double peak = 0.0;
  for (double v : input.values) peak = std::max(peak, std::abs(v));
  const double noise = 64.0 * std::numeric_limits<double>::epsilon() * peak;
  int kmax_used = kmax;
  while (kmax_used > 0 && std::hypot(a[kmax_used], b[kmax_used]) <= noise) --kmax_used;
  a.resize(kmax_used + 1);
  b.resize(kmax_used + 1);
  const double w = 2.0 * std::numbers::pi * input.frequency;
  return InputSignal([a = std::move(a), b = std::move(b), w, kmax = kmax_used](double t) {
    // Harmonics by rotation: one sin/cos per call, O(n) multiply-adds.
    const double c1 = std::cos(w * t), s1 = std::sin(w * t);
    double ck = 1.0, sk = 0.0;
    InputSample out{a[0], 0.0, 0.0};
    for (int k = 1; k <= kmax; ++k) {
      const double c = ck * c1 - sk * s1;
      sk = sk * c1 + ck * s1;
      ck = c;
      const double kw = k * w;
      out.value += a[k] * ck + b[k] * sk;
      out.rate += kw * (b[k] * ck - a[k] * sk);
      out.accel -= kw * kw * (a[k] * ck + b[k] * sk);
    }
    return out;
  });
}

std::vector<double> UniformTimes(double t_end, double rate) {
  if (!(t_end > 0) || !std::isfinite(t_end) || !(rate > 0) || !std::isfinite(rate))
    throw std::invalid_argument(fmt::format("output times: need t_end > 0 and rate > 0, got {} s and {} Hz", t_end, rate));
  const long count = static_cast<long>(std::floor(t_end * rate * (1.0 + 1e-12)));
  if (count > 100'000'000) throw std::invalid_argument(fmt::format("output times: {} samples is too many", count));
  std::vector<double> t;
  t.reserve(count + 2);
  for (long i = 0; i <= count; ++i) t.push_back(std::min(i / rate, t_end));
  if (t.back() < t_end) t.push_back(t_end);
  return t;
}

// ---------------------------------------------------------------------------------------------
// Options

bool TransientOptions::IsValid(std::string* error) const {
  const auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (!std::isfinite(rtol) || rtol < 1e-14 || rtol > 0.1)
    return fail(fmt::format("rtol must be between 1e-14 and 0.1 (double precision limits IDA), got {}", rtol));
  if (!std::isfinite(atol_factor) || !(atol_factor > 0)) return fail("atol_factor must be positive");
  if (!std::isfinite(max_step) || max_step < 0) return fail("max_step must be 0 (no limit) or positive");
  if (max_steps < 1) return fail("max_steps must be at least 1");
  if (max_order < 1 || max_order > 5) return fail("max_order must be 1..5");
  return true;
}

bool SteadyStateOptions::IsValid(std::string* error) const {
  const auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (periods_max < 2) return fail("periods_max must be at least 2 (periods are compared pairwise)");
  if (!std::isfinite(tol) || !(tol > 0)) return fail("tol must be positive");
  if (!std::isfinite(relative_floor) || relative_floor < 0) return fail("relative_floor must not be negative");
  return true;
}

Eigen::VectorXd TransientResult::channel(std::string_view name) const {
  for (std::size_t c = 0; c < channels.size(); ++c)
    if (channels[c] == name) return outputs.row(static_cast<int>(c)).transpose();
  throw std::out_of_range(fmt::format("transient result has no channel '{}'", name));
}

// ---------------------------------------------------------------------------------------------
// The DAE

DaeSystem::DaeSystem(Model model, std::vector<double> theta, Load load)
    : model_(std::move(model)), theta_(std::move(theta)), load_(std::move(load)) {
  m_ = model_.unknown_count();
  size_ = model_.causality() == Causality::kForceInput ? m_ + 1 : m_;
  if (static_cast<int>(theta_.size()) != model_.parameter_count())
    throw std::invalid_argument(fmt::format("transient: {} parameter values for model '{}' with {}", theta_.size(),
                                            model_.composition(), model_.parameter_count()));
  if (std::holds_alternative<DropLoad>(load_) && model_.causality() != Causality::kForceInput)
    throw std::invalid_argument("transient: a drop load needs the force-input form of the model");
  if (const auto* in = std::get_if<InputSignal>(&load_); in && !in->valid())
    throw std::invalid_argument("transient: the input signal is empty");
  if (2 * size_ > ident::kMaxDerivatives)
    throw std::invalid_argument(fmt::format("transient: model '{}' has too many unknowns for the Jacobian Jets",
                                            model_.composition()));
}

std::vector<bool> DaeSystem::differential() const {
  std::vector<bool> d(size_);
  for (int j = 0; j < m_; ++j) d[j] = model_.derivative_order(j) > 0;
  if (has_stroke_rate()) d[m_] = true;
  return d;
}

Eigen::VectorXd DaeSystem::scales() const {
  Eigen::VectorXd s(size_);
  for (int j = 0; j < m_; ++j) s[j] = model_.unknown_spec(j).scale;
  if (has_stroke_rate()) s[m_] = model_.unknown_spec(0).scale;  // m/s like the stroke in m
  return s;
}

InputSample DaeSystem::Input(double t, std::span<const double> yp) const {
  if (const auto* in = std::get_if<InputSignal>(&load_)) return (*in)(t);
  const auto& drop = std::get<DropLoad>(load_);
  return {drop.mass * (drop.gravity - yp[m_]), 0.0, 0.0};
}

template <class S>
void DaeSystem::Evaluate(double t, std::span<const S> y, std::span<const S> yp, std::span<S> r, int directions) const {
  const auto constant = [directions](double v) -> S {
    if constexpr (std::is_same_v<S, Jet>)
      return ident::MakeConstant(v, directions);
    else
      return v;
  };
  const int m = m_;
  std::vector<S> x(y.begin(), y.begin() + m), xd(m), xdd(m, constant(0.0));
  for (int j = 1; j < m; ++j) xd[j] = yp[j];
  S u, ud = constant(0.0), udd = constant(0.0);
  if (const auto* in = std::get_if<InputSignal>(&load_)) {
    const InputSample s = (*in)(t);
    u = constant(s.value);
    ud = constant(s.rate);
    udd = constant(s.accel);
  } else {
    // Mass-load mode: F = M (g - q'') as an expression in Y', so the Jacobian sees M.
    const auto& drop = std::get<DropLoad>(load_);
    u = (drop.gravity - yp[m]) * drop.mass;
  }
  if (has_stroke_rate()) {
    // First-order form: the model sees q' = v and q'' = v'; v - q' = 0 closes the system.
    xd[0] = y[m];
    xdd[0] = yp[m];
    r[m] = y[m] - yp[0];
  } else {
    xd[0] = yp[0];  // the force rate: the model does not use it
  }
  std::span<const S> theta_span;
  std::vector<S> theta_jets;
  if constexpr (std::is_same_v<S, Jet>) {
    theta_jets.reserve(theta_.size());
    for (double v : theta_) theta_jets.push_back(constant(v));
    theta_span = theta_jets;
  } else {
    theta_span = theta_;
  }
  model_.Residual<S>(x, xd, xdd, u, ud, udd, theta_span, r.first(m));
}

void DaeSystem::Residual(double t, std::span<const double> y, std::span<const double> yp, std::span<double> r) const {
  Evaluate<double>(t, y, yp, r, 0);
}

Eigen::MatrixXd DaeSystem::Jacobian(double t, std::span<const double> y, std::span<const double> yp, double cj) const {
  const int n = size_, directions = 2 * size_;
  std::vector<Jet> yj(n), ypj(n), r(n);
  for (int j = 0; j < n; ++j) {
    yj[j] = Jet(y[j], ident::DerivativeVector::Unit(directions, j));
    ypj[j] = Jet(yp[j], ident::DerivativeVector::Unit(directions, n + j));
  }
  Evaluate<Jet>(t, yj, ypj, r, directions);
  Eigen::MatrixXd jac = Eigen::MatrixXd::Zero(n, n);
  for (int i = 0; i < n; ++i) {
    const auto& d = r[i].derivatives();
    if (d.size() != directions) continue;  // an equation that depends on nothing
    for (int j = 0; j < n; ++j) jac(i, j) = d[j] + cj * d[n + j];
  }
  return jac;
}

// ---------------------------------------------------------------------------------------------
// IDAS (ida_run.h)

struct TransientSimulator::Context : detail::SundialsContext {};

namespace {

// Y and a Y' guess at t = 0 from the model's unknowns (IDACalcIC completes Y').
void StartVectors(const DaeSystem& system, std::span<const double> x0, double stroke_rate, std::vector<double>& y,
                  std::vector<double>& yp) {
  const int m = system.unknown_count();
  y.assign(system.size(), 0.0);
  yp.assign(system.size(), 0.0);
  std::copy(x0.begin(), x0.end(), y.begin());
  if (system.has_stroke_rate()) {
    y[m] = stroke_rate;
    yp[0] = stroke_rate;
  }
}

void CheckTheta(const Model& model, std::span<const double> theta) {
  if (static_cast<int>(theta.size()) != model.parameter_count())
    throw std::invalid_argument(fmt::format("transient: {} parameter values for model '{}' with {}", theta.size(),
                                            model.composition(), model.parameter_count()));
  for (std::size_t i = 0; i < theta.size(); ++i)
    if (!std::isfinite(theta[i]))
      throw std::invalid_argument(
          fmt::format("transient: parameter {} is not finite", model.defaults().spec(static_cast<int>(i)).key()));
}

std::vector<std::string> UnknownNames(const Model& model) {
  std::vector<std::string> names;
  for (int j = 0; j < model.unknown_count(); ++j) names.push_back(model.unknown_spec(j).name);
  return names;
}

// The model's unknowns at t = 0: given, or the static equilibrium at u(0).
std::vector<double> InitialUnknowns(const Model& model, std::span<const double> theta, const InputSignal& input,
                                    const InitialState& initial) {
  const int m = model.unknown_count();
  if (!initial.unknowns.empty()) {
    if (static_cast<int>(initial.unknowns.size()) != m)
      throw std::invalid_argument(fmt::format("transient: {} initial unknowns for model '{}' with {}",
                                              initial.unknowns.size(), model.composition(), m));
    for (double v : initial.unknowns)
      if (!std::isfinite(v)) throw std::invalid_argument("transient: the initial unknowns are not finite");
    return initial.unknowns;
  }
  const InputSample u0 = input(0.0);
  if (!std::isfinite(u0.value) || !std::isfinite(u0.rate) || !std::isfinite(u0.accel))
    throw TransientError(fmt::format("transient: the input is not finite at t = 0 (u = {})", u0.value), 0.0, 0);
  return model.StaticEquilibrium(u0.value, theta);
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Simulator

TransientSimulator::TransientSimulator(Model model, TransientOptions options)
    : model_(std::move(model)), options_(options) {
  std::string error;
  if (!options_.IsValid(&error)) throw std::invalid_argument("transient options: " + error);
  context_ = std::make_unique<Context>();
}

TransientSimulator::~TransientSimulator() = default;
TransientSimulator::TransientSimulator(TransientSimulator&&) noexcept = default;
TransientSimulator& TransientSimulator::operator=(TransientSimulator&&) noexcept = default;

TransientResult TransientSimulator::Simulate(std::span<const double> theta, const InputSignal& input,
                                             std::span<const double> output_times, const InitialState& initial) const {
  return Run(model_, theta, input, output_times, initial);
}

TransientResult TransientSimulator::Simulate(std::span<const double> theta, const InputSignal& input, double t_end,
                                             double output_rate, const InitialState& initial) const {
  return Run(model_, theta, input, UniformTimes(t_end, output_rate), initial);
}

TransientResult TransientSimulator::Simulate(std::span<const double> theta, const DropLoad& load,
                                             std::span<const double> output_times) const {
  if (!(load.mass > 0) || !std::isfinite(load.mass) || !std::isfinite(load.impact_velocity) ||
      !std::isfinite(load.gravity))
    throw std::invalid_argument(fmt::format("drop load: needs a positive mass and finite velocity and gravity, got "
                                            "M = {} kg, v0 = {} m/s, g = {} m/s^2",
                                            load.mass, load.impact_velocity, load.gravity));
  // The drop is force-driven whatever causality the model was built with.
  const Model force_model = model_.causality() == Causality::kForceInput
                                ? model_
                                : Model::Build(model_.composition(), Causality::kForceInput);
  CheckTheta(force_model, theta);
  return Run(force_model, theta, load, output_times, DropContactState(model_, theta, load));
}

InitialState DropContactState(const Model& model, std::span<const double> theta, const DropLoad& load) {
  // States at q = 0 at rest (T ambient): the stroke-input static equilibrium at the measured
  // stroke of q = 0, which is the sensor offset theta12 when the model has one.
  const Model stroke_model = model.causality() == Causality::kStrokeInput
                                 ? model
                                 : Model::Build(model.composition(), Causality::kStrokeInput);
  const int offset = stroke_model.defaults().position_of_index(12);
  const double measured_zero = offset >= 0 && stroke_model.has_term("stroke-offset") ? theta[offset] : 0.0;
  std::vector<double> x0 = stroke_model.StaticEquilibrium(measured_zero, theta);
  x0[0] = 0.0;  // the force slot becomes the stroke
  return InitialState{x0, load.impact_velocity};
}

TransientResult TransientSimulator::Simulate(std::span<const double> theta, const DropLoad& load, double t_end,
                                             double output_rate) const {
  const auto times = UniformTimes(t_end, output_rate);
  return Simulate(theta, load, times);
}

TransientResult TransientSimulator::Run(const Model& model, std::span<const double> theta, const Load& load,
                                        std::span<const double> output_times, const InitialState& initial) const {
  const auto start = std::chrono::steady_clock::now();
  CheckTheta(model, theta);
  if (output_times.empty()) throw std::invalid_argument("transient: no output times");
  for (std::size_t i = 0; i < output_times.size(); ++i) {
    const double t = output_times[i];
    if (!std::isfinite(t) || t < 0 || (i > 0 && !(t > output_times[i - 1])))
      throw std::invalid_argument(
          fmt::format("transient: output times must be finite, >= 0 and increasing (time {} is {})", i, t));
  }
  const double t_end = output_times.back();
  if (!(t_end > 0)) throw std::invalid_argument("transient: the last output time must be positive");

  const DaeSystem system(model, std::vector<double>(theta.begin(), theta.end()), load);
  std::vector<double> x0;
  if (const auto* in = std::get_if<InputSignal>(&load)) {
    x0 = InitialUnknowns(model, theta, *in, initial);
  } else {
    x0 = initial.unknowns;
  }
  std::vector<double> y0, yp0;
  StartVectors(system, x0, initial.stroke_rate, y0, yp0);

  detail::IdaRun ida(context_->ctx, system, options_, y0, yp0);
  const double first_positive = *std::find_if(output_times.begin(), output_times.end(), [](double t) { return t > 0; });
  ida.ConsistentStart(first_positive);

  const int m = model.unknown_count();
  const int k = static_cast<int>(output_times.size());
  TransientResult result;
  result.time.assign(output_times.begin(), output_times.end());
  result.unknown_names = UnknownNames(model);
  result.channels = model.output_channels();
  result.unknowns.resize(m, k);
  result.rates.resize(m, k);
  result.input.resize(k);
  result.outputs.resize(static_cast<int>(result.channels.size()), k);
  std::vector<double> out(result.channels.size());
  for (int i = 0; i < k; ++i) {
    if (output_times[i] > 0) ida.AdvanceTo(output_times[i], t_end);
    const auto y = ida.y();
    const auto yp = ida.yp();
    for (int j = 0; j < m; ++j) {
      result.unknowns(j, i) = y[j];
      result.rates(j, i) = (j == 0 && system.has_stroke_rate()) ? y[m] : yp[j];
    }
    const double u = system.Input(output_times[i], yp).value;
    result.input[i] = u;
    model.Outputs<double>(y.first(m), u, theta, out);
    for (std::size_t c = 0; c < out.size(); ++c) result.outputs(static_cast<int>(c), i) = out[c];
  }
  result.steps = ida.steps();
  result.residual_evaluations = ida.residual_evaluations();
  result.jacobian_evaluations = ida.jacobian_evaluations();
  result.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

PeriodicSteadyStateResult TransientSimulator::PeriodicSteadyState(std::span<const double> theta,
                                                                  const ident::PeriodicInput& input,
                                                                  const SteadyStateOptions& steady,
                                                                  const InitialState& initial) const {
  const auto start = std::chrono::steady_clock::now();
  std::string error;
  if (!steady.IsValid(&error)) throw std::invalid_argument("steady-state options: " + error);
  CheckTheta(model_, theta);
  const InputSignal signal = InputSignal::FromPeriodic(input);  // validates the grid
  const int n = static_cast<int>(input.values.size());
  const int m = model_.unknown_count();
  const double f = input.frequency;

  const DaeSystem system(model_, std::vector<double>(theta.begin(), theta.end()), signal);
  std::vector<double> y0, yp0;
  StartVectors(system, InitialUnknowns(model_, theta, signal, initial), initial.stroke_rate, y0, yp0);
  detail::IdaRun ida(context_->ctx, system, options_, y0, yp0);
  ida.ConsistentStart(1.0 / (n * f));

  Eigen::VectorXd scale(m);
  for (int j = 0; j < m; ++j) scale[j] = model_.unknown_spec(j).scale;
  Eigen::MatrixXd current(m, n), previous(m, n);
  const auto store = [&](int mu) {
    for (int j = 0; j < m; ++j) current(j, mu) = ida.y()[j];
  };
  // Grid times from integers, so no drift accumulates over many periods.
  const auto grid_time = [&](long period, int mu) { return static_cast<double>(period * n + mu) / (n * f); };

  PeriodicSteadyStateResult result;
  detail::PeriodConvergence convergence;
  bool converged = false;
  store(0);
  int period = 0;
  for (; period < steady.periods_max && !converged; ++period) {
    const double period_end = grid_time(period + 1, 0);
    for (int mu = 1; mu < n; ++mu) {
      ida.AdvanceTo(grid_time(period, mu), period_end);
      store(mu);
    }
    if (period > 0)
      converged = convergence.Add(detail::PeriodChange(current, previous, scale, steady.relative_floor), steady.tol);
    if (converged) break;
    previous = current;
    ida.AdvanceTo(period_end, period_end);
    store(0);
  }
  if (!converged)
    throw TransientError(fmt::format("transient: no periodic steady state after {} periods of {:.6g} s: the last "
                                     "change between periods is {:.3g} scaled units (tolerance {:.3g})",
                                     steady.periods_max, 1.0 / f, convergence.change(), steady.tol),
                         ida.time(), 0);

  ident::PeriodicSolution& s = result.solution;
  s.frequency = f;
  s.n = n;
  s.unknowns = current;
  s.input = input;
  s.channels = model_.output_channels();
  s.outputs.resize(static_cast<int>(s.channels.size()), n);
  std::vector<double> out(s.channels.size());
  for (int mu = 0; mu < n; ++mu) {
    // The grid value is what the periodic solver sees; the interpolant equals it at t_mu.
    model_.Outputs<double>(std::span<const double>(current.col(mu).data(), m), input.values[mu], theta, out);
    for (std::size_t c = 0; c < out.size(); ++c) s.outputs(static_cast<int>(c), mu) = out[c];
  }
  result.periods = period + 1;
  result.last_change = convergence.change();
  result.estimated_error = convergence.estimate();
  result.steps = ida.steps();
  result.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

PeriodicSteadyStateResult PeriodicSteadyState(const Model& model, std::span<const double> theta,
                                              const ident::PeriodicInput& input, int periods_max, double tol,
                                              const TransientOptions& options) {
  SteadyStateOptions steady;
  steady.periods_max = periods_max;
  steady.tol = tol;
  return TransientSimulator(model, options).PeriodicSteadyState(theta, input, steady);
}

}  // namespace strut::sim
