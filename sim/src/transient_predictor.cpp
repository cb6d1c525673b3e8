#include "strut/sim/transient_predictor.h"

#include "ida_run.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fmt/format.h>
#include <limits>
#include <optional>
#include <set>

namespace strut::sim {

using ident::Causality;
using ident::DerivativeVector;
using ident::Jet;
using ident::Model;
using ident::PeriodicSolverError;

bool TransientPredictorOptions::IsValid(std::string* error) const {
  const auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  std::string inner;
  if (!integrator.IsValid(&inner)) return fail("integrator: " + inner);
  if (!steady.IsValid(&inner)) return fail("steady state: " + inner);
  if (!std::isfinite(sensitivity_relative_tol) || !(sensitivity_relative_tol > 0))
    return fail("sensitivity_relative_tol must be positive");
  return true;
}

TransientPredictorStats& TransientPredictorStats::operator+=(const TransientPredictorStats& o) {
  solves += o.solves;
  solve_periods += o.solve_periods;
  solve_steps += o.solve_steps;
  solve_seconds += o.solve_seconds;
  sensitivity_runs += o.sensitivity_runs;
  sensitivity_periods += o.sensitivity_periods;
  sensitivity_steps += o.sensitivity_steps;
  sensitivity_seconds += o.sensitivity_seconds;
  return *this;
}

// ---------------------------------------------------------------------------------------------
// The sensitivity residuals (the DAE of DaeSystem with the parameters as Jet directions too)

Eigen::MatrixXd SensitivityResiduals(const Model& model, std::span<const double> theta, const InputSignal& input,
                                     std::span<const int> parameters, double t, std::span<const double> y,
                                     std::span<const double> yp, const Eigen::MatrixXd& s, const Eigen::MatrixXd& sp,
                                     Eigen::VectorXd* values) {
  return SensitivityResiduals(model, theta, Load(input), parameters, t, y, yp, s, sp, values);
}

Eigen::MatrixXd SensitivityResiduals(const Model& model, std::span<const double> theta, const Load& load,
                                     std::span<const int> parameters, double t, std::span<const double> y,
                                     std::span<const double> yp, const Eigen::MatrixXd& s, const Eigen::MatrixXd& sp,
                                     Eigen::VectorXd* values) {
  const int m = model.unknown_count();
  const bool force_input = model.causality() == Causality::kForceInput;
  const int size = force_input ? m + 1 : m;
  const int ns = static_cast<int>(parameters.size());
  const auto constant = [ns](double v) { return ident::MakeConstant(v, ns); };
  std::vector<Jet> Y(size), YP(size);
  for (int j = 0; j < size; ++j) {
    Y[j] = Jet(y[j], DerivativeVector(s.row(j).transpose()));
    YP[j] = Jet(yp[j], DerivativeVector(sp.row(j).transpose()));
  }
  std::vector<Jet> x(Y.begin(), Y.begin() + m), xd(m), xdd(m, constant(0.0)), r(size);
  for (int j = 1; j < m; ++j) xd[j] = YP[j];
  if (force_input) {
    // First-order form of DaeSystem: the model sees q' = v, q'' = v'; v - q' = 0 closes the system.
    xd[0] = Y[m];
    xdd[0] = YP[m];
    r[m] = Y[m] - YP[0];
  } else {
    xd[0] = YP[0];
  }
  std::vector<Jet> theta_jet;
  theta_jet.reserve(theta.size());
  for (double v : theta) theta_jet.push_back(constant(v));
  for (int k = 0; k < ns; ++k) theta_jet[parameters[k]] = Jet(theta[parameters[k]], DerivativeVector::Unit(ns, k));
  Jet u, ud = constant(0.0), udd = constant(0.0);
  if (const auto* input = std::get_if<InputSignal>(&load)) {
    const InputSample sample = (*input)(t);
    u = constant(sample.value);
    ud = constant(sample.rate);
    udd = constant(sample.accel);
  } else {
    // Mass-load mode, as DaeSystem::Evaluate: F = M (g - v') with v' (and its sensitivity) from Y'.
    if (!force_input) throw std::invalid_argument("sensitivity residuals: a drop load needs the force-input form");
    const DropLoad& drop = std::get<DropLoad>(load);
    u = (constant(drop.gravity) - YP[m]) * drop.mass;
  }
  model.Residual<Jet>(x, xd, xdd, u, ud, udd, theta_jet, std::span<Jet>(r).first(m));
  Eigen::MatrixXd out(size, ns);
  if (values) values->resize(size);
  for (int i = 0; i < size; ++i) {
    const auto& d = r[i].derivatives();
    for (int k = 0; k < ns; ++k) out(i, k) = d.size() == ns ? d[k] : 0.0;
    if (values) (*values)[i] = r[i].value();
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// IDAS (ida_run.h)

struct TransientPredictor::Ida : detail::SundialsContext {};

namespace {

//! q'(t_mu) from the stroke on the periodic grid (fourth-order central differences), m/s.
double GridRate(const Eigen::MatrixXd& unknowns, int row, int mu, double frequency) {
  const int n = static_cast<int>(unknowns.cols());
  const ident::Stencil stencil = ident::Stencil::For(ident::Scheme::kCentral4, n);
  double rate = 0.0;
  for (int k = stencil.kmin; k <= stencil.kmax; ++k)
    rate += stencil.first[k - stencil.kmin] * unknowns(row, ((mu + k) % n + n) % n);
  return rate * frequency;
}

//! IDA integrates straight through the pole of the gas law when the stroke passes full compression
//! (gas volume through zero), so a "steady state" may hold a negative absolute pressure where the
//! periodic solver finds none. States that are positive by nature (positive typical value:
//! absolute pressure, temperature) must stay positive.
void CheckPhysical(const Model& model, const ident::PeriodicSolution& s) {
  if (!s.unknowns.allFinite() || !s.outputs.allFinite())
    throw PeriodicSolverError("transient predictor: the steady state is not finite", NAN, 0);
  for (int j = 1; j < model.unknown_count(); ++j) {
    const ident::StateSpec spec = model.unknown_spec(j);
    if (!(spec.typical_value > 0)) continue;
    Eigen::Index mu = 0;
    const double lowest = s.unknowns.row(j).minCoeff(&mu);
    if (lowest <= 0)
      throw PeriodicSolverError(fmt::format("transient predictor: no physical steady state: the {} reaches {:.4g} {} at "
                                            "t = {:.6g} s of the period (past full compression?)",
                                            spec.name, lowest, spec.unit, mu / (s.n * s.frequency)),
                                NAN, 0);
  }
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// The predictor

TransientPredictor::TransientPredictor(Model model, TransientPredictorOptions options)
    : model_(model), options_(std::move(options)), simulator_(model, options_.integrator) {
  std::string error;
  if (!options_.IsValid(&error)) throw std::invalid_argument("transient predictor options: " + error);
  ida_ = std::make_unique<Ida>();
}

TransientPredictor::~TransientPredictor() = default;

ident::PeriodicSolution TransientPredictor::Solve(const ident::PeriodicInput& input, std::span<const double> theta,
                                                  const ident::PeriodicSolution* warm_start) {
  const int n = static_cast<int>(input.values.size());
  const int m = model_.unknown_count();
  if (!input.phases.empty())  // its outputs are sampled at mu / n
    throw std::invalid_argument("transient predictor: the input must be on an equidistant grid (give the fit an n)");
  InitialState initial;
  if (warm_start && warm_start->n == n && warm_start->unknowns.rows() == m && warm_start->unknowns.cols() == n &&
      warm_start->unknowns.allFinite()) {
    initial.unknowns.assign(warm_start->unknowns.col(0).data(), warm_start->unknowns.col(0).data() + m);
    if (model_.causality() == Causality::kForceInput)
      initial.stroke_rate = GridRate(warm_start->unknowns, 0, 0, warm_start->frequency);
  }
  const auto run = [&](const InitialState& start) {
    PeriodicSteadyStateResult r = simulator_.PeriodicSteadyState(theta, input, options_.steady, start);
    ++stats_.solves;
    stats_.solve_periods += r.periods;
    stats_.solve_steps += r.steps;
    stats_.solve_seconds += r.wall_seconds;
    r.solution.newton_iterations = r.periods;  // the closest analogue: periods integrated
    r.solution.residual_norm = r.estimated_error;
    CheckPhysical(model_, r.solution);
    return std::move(r.solution);
  };
  try {
    try {
      return run(initial);
    } catch (const TransientError&) {
      if (initial.unknowns.empty()) throw;
      return run({});  // the warm start may be too far off for IDACalcIC: start from rest
    }
  } catch (const TransientError& e) {
    throw PeriodicSolverError(fmt::format("transient predictor: {}", e.what()), NAN, 0);
  } catch (const ident::ModelError& e) {
    throw PeriodicSolverError(fmt::format("transient predictor: no starting state: {}", e.what()), NAN, 0);
  }
}

namespace {

//! The positions `wanted` names (every parameter when it is empty), checked against the model.
std::vector<int> SensitivityParameters(const Model& model, std::span<const int> wanted) {
  const int np = model.parameter_count();
  std::vector<int> parameters(wanted.begin(), wanted.end());
  if (parameters.empty())
    for (int p = 0; p < np; ++p) parameters.push_back(p);
  if (std::set<int>(parameters.begin(), parameters.end()).size() != parameters.size())
    throw std::invalid_argument("transient predictor: a parameter is listed twice");
  for (int p : parameters)
    if (p < 0 || p >= np)
      throw std::invalid_argument(fmt::format("transient predictor: parameter position {} is not one of model '{}'", p,
                                              model.composition()));
  if (static_cast<int>(parameters.size()) > ident::kMaxDerivatives)
    throw std::invalid_argument("transient predictor: too many parameters for the sensitivity Jets");
  return parameters;
}

//! IDAS's parameter scales (pbar): the larger of |theta| and the parameter's typical size, 1 for
//! a parameter that has neither.
std::vector<double> ParameterScales(const Model& model, std::span<const double> theta,
                                    const std::vector<int>& parameters) {
  std::vector<double> pbar(parameters.size());
  for (std::size_t k = 0; k < parameters.size(); ++k) {
    const int i = parameters[k];
    pbar[k] = std::max({std::abs(theta[i]), model.defaults().spec(i).typical_size(), 1e-300});
    if (pbar[k] == 1e-300) pbar[k] = 1.0;
  }
  return pbar;
}

//! One period of the state (m x n) and of the sensitivities (DaeSystem size x n per parameter) on
//! the grid, once both repeat.
struct SensitivityPeriod {
  Eigen::MatrixXd state;
  std::vector<Eigen::MatrixXd> sens;
  int periods = 0;  //!< periods integrated
};

//! Integrates `ida` (state and sensitivities, at its consistent start) period by period until the
//! state (as TransientSimulator::PeriodicSteadyState measures it) and the sensitivities (in their
//! absolute tolerance or a fraction of their peak) repeat: the worse of the two, relative to its
//! tolerance, must be within it. Throws PeriodicSolverError when they do not within periods_max.
SensitivityPeriod IntegrateToPeriodic(detail::IdaRun& ida, const Model& model, const DaeSystem& system,
                                      const TransientPredictorOptions& options, const std::vector<double>& pbar,
                                      int n, double f) {
  const int m = model.unknown_count(), size = system.size(), ns = static_cast<int>(pbar.size());
  SensitivityPeriod p{Eigen::MatrixXd(m, n), std::vector<Eigen::MatrixXd>(ns, Eigen::MatrixXd(size, n)), 0};
  Eigen::MatrixXd previous_state(m, n);
  std::vector<Eigen::MatrixXd> previous_sens(ns);
  const auto store = [&](int mu) {
    for (int j = 0; j < m; ++j) p.state(j, mu) = ida.y()[j];
    for (int k = 0; k < ns; ++k)
      for (int j = 0; j < size; ++j) p.sens[k](j, mu) = ida.s(j, k);
  };
  const auto grid_time = [&](long period, int mu) { return static_cast<double>(period * n + mu) / (n * f); };
  Eigen::VectorXd scale(size);
  scale = system.scales() * options.integrator.atol_factor;  // absolute tolerances of Y
  Eigen::VectorXd state_scale(m);
  for (int j = 0; j < m; ++j) state_scale[j] = model.unknown_spec(j).scale;

  detail::PeriodConvergence convergence;
  bool converged = false;
  int period = 0;
  store(0);
  for (; period < options.steady.periods_max && !converged; ++period) {
    const double period_end = grid_time(period + 1, 0);
    for (int mu = 1; mu < n; ++mu) {
      ida.AdvanceTo(grid_time(period, mu), period_end);
      store(mu);
    }
    if (period > 0) {
      double d = detail::PeriodChange(p.state, previous_state, state_scale, options.steady.relative_floor) /
                 options.steady.tol;
      for (int k = 0; k < ns; ++k)
        d = std::max(d, detail::PeriodChange(p.sens[k], previous_sens[k], scale / pbar[k],
                                             options.sensitivity_relative_tol));
      converged = convergence.Add(d, 1.0);
    }
    if (converged) break;
    previous_state = p.state;
    previous_sens = p.sens;
    ida.AdvanceTo(period_end, period_end);
    store(0);
  }
  if (!converged)
    throw PeriodicSolverError(fmt::format("transient predictor: the sensitivities are not periodic after {} periods of "
                                          "{:.6g} s (last change {:.3g} of the tolerance)",
                                          options.steady.periods_max, 1.0 / f, convergence.change()),
                              convergence.change(), period);
  p.periods = period + 1;
  return p;
}

//! d yhat / d theta = dOut/dx s_x + dOut/dtheta on the grid (the outputs of PeriodicSolution: grid
//! input values), one n x parameters matrix per output channel.
std::vector<Eigen::MatrixXd> OutputJacobians(const Model& model, const ident::PeriodicSolution& solution,
                                             std::span<const double> theta, const std::vector<int>& parameters,
                                             const SensitivityPeriod& period) {
  const int n = solution.n, m = model.unknown_count(), ns = static_cast<int>(parameters.size());
  const int channels = static_cast<int>(solution.channels.size());
  std::vector<Eigen::MatrixXd> out(channels, Eigen::MatrixXd(n, ns));
  std::vector<Jet> theta_jet;
  for (double v : theta) theta_jet.push_back(ident::MakeConstant(v, ns));
  for (int k = 0; k < ns; ++k) theta_jet[parameters[k]] = Jet(theta[parameters[k]], DerivativeVector::Unit(ns, k));
  std::vector<Jet> xs(m), y(channels);
  for (int mu = 0; mu < n; ++mu) {
    for (int j = 0; j < m; ++j) {
      DerivativeVector d(ns);
      for (int k = 0; k < ns; ++k) d[k] = period.sens[k](j, mu);
      xs[j] = Jet(period.state(j, mu), d);
    }
    model.Outputs<Jet>(xs, ident::MakeConstant(solution.input.values[mu], ns), theta_jet, y);
    for (int c = 0; c < channels; ++c) {
      const auto& d = y[c].derivatives();
      for (int k = 0; k < ns; ++k) out[c](mu, k) = d.size() == ns ? d[k] : 0.0;
    }
  }
  return out;
}

}  // namespace

std::vector<Eigen::MatrixXd> TransientPredictor::OutputSensitivities(const ident::PeriodicSolution& solution,
                                                                     std::span<const double> theta,
                                                                     std::span<const int> wanted, bool) {
  const auto start = std::chrono::steady_clock::now();
  const int n = solution.n;
  const int m = model_.unknown_count();
  const int np = model_.parameter_count();
  if (static_cast<int>(theta.size()) != np)
    throw std::invalid_argument(fmt::format("transient predictor: {} parameter values for model '{}' with {}",
                                            theta.size(), model_.composition(), np));
  if (n < 5 || solution.unknowns.rows() != m || solution.unknowns.cols() != n || !solution.unknowns.allFinite())
    throw std::invalid_argument("transient predictor: sensitivities need a periodic solution of this model");
  const std::vector<int> parameters = SensitivityParameters(model_, wanted);
  const int ns = static_cast<int>(parameters.size());
  const double f = solution.frequency;

  const InputSignal signal = InputSignal::FromPeriodic(solution.input);
  const DaeSystem system(model_, std::vector<double>(theta.begin(), theta.end()), signal);
  const int size = system.size();
  Eigen::VectorXd y0(size);
  y0.head(m) = solution.unknowns.col(0);
  if (system.has_stroke_rate()) y0[m] = GridRate(solution.unknowns, 0, 0, f);
  const bool warm = sensitivity_start_.rows() == size && sensitivity_start_.cols() == ns && sensitivity_frequency_ == f &&
                    sensitivity_start_.allFinite();
  const Eigen::MatrixXd s0 = warm ? sensitivity_start_ : Eigen::MatrixXd::Zero(size, ns);
  const std::vector<double> pbar = ParameterScales(model_, theta, parameters);

  const Load load = signal;
  detail::SensitivitySetup setup;
  setup.load = &load;
  setup.theta = theta;
  setup.parameters = parameters;
  setup.start = s0;
  setup.pbar = pbar;
  setup.staggered = options_.staggered;
  setup.error_control = options_.sensitivity_error_control;
  Eigen::VectorXd yp0 = Eigen::VectorXd::Zero(size);  // IDACalcIC completes Y'
  if (system.has_stroke_rate()) yp0[0] = y0[m];
  std::optional<detail::IdaRun> ida;
  SensitivityPeriod period;
  try {
    ida.emplace(ida_->ctx, system, options_.integrator, std::span<const double>(y0.data(), size),
                std::span<const double>(yp0.data(), size), &setup);
    ida->ConsistentStart(1.0 / (n * f));
    period = IntegrateToPeriodic(*ida, model_, system, options_, pbar, n, f);
  } catch (const TransientError& e) {
    throw PeriodicSolverError(fmt::format("transient predictor: sensitivities: {}", e.what()), NAN, 0);
  }

  sensitivity_start_.resize(size, ns);
  for (int k = 0; k < ns; ++k) sensitivity_start_.col(k) = period.sens[k].col(0);
  sensitivity_frequency_ = f;
  std::vector<Eigen::MatrixXd> out = OutputJacobians(model_, solution, theta, parameters, period);
  ++stats_.sensitivity_runs;
  stats_.sensitivity_periods += period.periods;
  stats_.sensitivity_steps += ida->steps();
  stats_.sensitivity_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace strut::sim
