#include "strut/ident/estimator.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <exception>
#include <mutex>
#include <optional>
#include <thread>
#include <cmath>
#include <fmt/format.h>
#include <numbers>
#include <numeric>
#include <set>
#include <spdlog/spdlog.h>
#include <unsupported/Eigen/FFT>

namespace strut::ident {
namespace {

std::vector<std::string> DefaultChannels(const Model& model) {
  // The mechanical output (stroke under force input, force under stroke input; y for a generic
  // oscillator) and the gas pressure when the model has one.
  std::vector<std::string> channels = {model.mechanical_channel()};
  const auto& states = model.states();
  if (std::any_of(states.begin(), states.end(), [](const StateSpec& s) { return s.name == "pressure"; }))
    channels.push_back("pressure");
  return channels;
}

//! The covariance that the noise of a measured input puts on a gradient: for g = dF/du on the
//! n-point input grid (one column per function F), sum over the input's noisy Fourier coefficients
//! c of var(c) (dF/dc)(dF/dc)^T, where dF/dc is g projected on that coefficient's grid function
//! (the mean: 1; harmonic h: cos and sin of 2 pi h mu / n). The projections are one FFT per column.
Eigen::MatrixXd InputNoiseCovariance(const ExperimentData& d, const Eigen::MatrixXd& gradient) {
  const Eigen::Index k = gradient.cols();
  const int n = static_cast<int>(gradient.rows());
  Eigen::MatrixXd covariance = Eigen::MatrixXd::Zero(k, k);
  if (!(d.input_harmonic_variance > 0) || d.input_harmonics.empty() || k == 0) return covariance;
  Eigen::FFT<double> fft;
  Eigen::MatrixXcd spectra(n, k);  // sum_mu g(mu) exp(-i 2 pi h mu / n)
  for (Eigen::Index b = 0; b < k; ++b) {
    Eigen::VectorXcd column(n);
    fft.fwd(column, Eigen::VectorXd(gradient.col(b)));
    spectra.col(b) = column;
  }
  for (const int h : d.input_harmonics) {
    if (h >= n) continue;
    if (h == 0) {
      const Eigen::VectorXd q = spectra.row(0).real().transpose();
      covariance.noalias() += d.input_mean_variance * q * q.transpose();
      continue;
    }
    // cos: Re of the spectrum; sin: -Im (the sign drops out of q q^T).
    const Eigen::VectorXd qc = spectra.row(h).real().transpose(), qs = spectra.row(h).imag().transpose();
    covariance.noalias() += d.input_harmonic_variance * (qc * qc.transpose() + qs * qs.transpose());
  }
  return covariance;
}

//! The composition of a force-driven damper model under stroke input, for MeasuredStrokeStart;
//! empty for other models.
std::optional<Model> StrokeDrivenTwin(const Model& model) {
  if (model.causality() != Causality::kForceInput || model.mechanical_channel() != "stroke") return std::nullopt;
  try {
    Model twin = Model::Build(model.composition(), Causality::kStrokeInput);
    if (twin.unknown_count() == model.unknown_count()) return twin;
  } catch (const ModelError&) {
  }
  return std::nullopt;
}

constexpr double kMeasuredStartMismatch = 0.1;  // rms over the force's range, periodic solution
constexpr double kStaticStartMismatch = 1.0;    // largest over the force's range, static solutions

//! A first guess for a force-driven experiment from what was measured: the recorded stroke (less
//! its sensor offset) and the states of the stroke-driven model on it. From the quasi-static guess a
//! cold solve must find the response to the measured force's noise and friction jumps itself (3-11
//! factorisations on the standard matrix); from here it needs 3-8. Empty when the model is not a
//! force-driven damper, the stroke was not recorded, the stroke-driven solve fails, or the model on
//! the measured stroke misses the measured force (parameters far from the record's).
//! `stroke_driven`: the same composition under stroke input (StrokeDrivenTwin).
std::optional<PeriodicSolution> MeasuredStrokeStart(const Model& model, const Model& stroke_driven,
                                                    const ExperimentData& d, std::span<const double> theta, int n,
                                                    const PeriodicSolverOptions& options) {
  const auto stroke = d.channels.find("stroke");
  if (stroke == d.channels.end() || stroke->second.mean.size() < 8) return std::nullopt;
  try {
    const PeriodicSeries series = PeriodicSeries::Fit(stroke->second.mean, d.frequency);
    const PeriodicInput measured = series.OnGrid(n);
    const Eigen::Map<const Eigen::VectorXd> force(d.input.values.data(), n);
    const double range = force.maxCoeff() - force.minCoeff();
    // A cheap first test (8 static solves): far from the parameters that explain the record the
    // stroke-driven solve below can take as long as a failed cold solve. On the standard matrix the
    // static force misses the measured one by 0.14-0.48 of its range at the truth, 0.56-348 from
    // 20 % off (experiments a and b: 5-12).
    std::vector<double> at_rest;
    for (int mu = 0; mu < n; mu += std::max(1, n / 8)) {
      at_rest = stroke_driven.StaticEquilibrium(measured.values[mu], theta, at_rest);
      if (!(std::abs(at_rest[0] - force[mu]) <= kStaticStartMismatch * range)) return std::nullopt;
    }
    // The states only start Newton: the stroke-driven solution on the coarse grid (a third of
    // the cost of this start), interpolated.
    const int coarse = options.coarse_points >= 8 && n >= 2 * options.coarse_points && n % options.coarse_points == 0
                           ? options.coarse_points
                           : n;
    PeriodicSolverOptions coarse_options = options;
    coarse_options.coarse_points = 0;
    PeriodicSolver solver(stroke_driven, coarse_options);
    const PeriodicSolution states = solver.Solve(series.OnGrid(coarse), theta);
    // Only near the parameters that explain the record: the model driven by the measured stroke
    // must predict the measured force within a tenth of its range (rms). On the standard matrix
    // that is 0.0002-0.04 at the truth and 0.45-86 from 20 % off, where this start is worse than
    // the quasi-static guess and the force-driven Newton can fail from it.
    const Eigen::VectorXd predicted = states.channel("force");
    const int stride = n / coarse;
    double mismatch = 0.0;
    for (int k = 0; k < coarse; ++k) mismatch += std::pow(predicted[k] - force[k * stride], 2);
    if (!(std::sqrt(mismatch / coarse) <= kMeasuredStartMismatch * range)) return std::nullopt;
    // The stroke unknown is the true stroke: the measured one less the output a zero stroke has
    // (the sensor offset, when the model has one).
    const int m = model.unknown_count();
    std::vector<double> zero(m, 0.0), outputs(model.output_channels().size());
    model.Outputs<double>(zero, 0.0, theta, outputs);
    PeriodicSolution guess;
    guess.scheme = options.scheme;
    guess.frequency = d.frequency;
    guess.n = n;
    guess.unknowns = PeriodicResample(states.unknowns, n);
    for (int mu = 0; mu < n; ++mu) guess.unknowns(0, mu) = measured.values[mu] - outputs[0];
    return guess;
  } catch (const std::exception& e) {  // no stroke-driven solution there: the usual cold start
    spdlog::debug("experiment '{}': no start from the measured stroke ({})", d.label, e.what());
    return std::nullopt;
  }
}

// Everything one iterate of the fit needs per experiment.
struct ExperimentState {
  const ExperimentData* data = nullptr;
  std::unique_ptr<PeriodicPredictor> solver;
  PeriodicSolution solution;
  bool active = true;
  std::vector<bool> channel_fitted;  // per fitted channel: false when the channel has a data defect
  std::string error;
  bool dropped_at_start = false;      // no solution at the starting values; retried as the fit moves
  //! Per fitted channel, d(prediction at the phases)/d(scaled parameters) of the last iteration that
  //! computed them: reused while the fit's steps are below a percent of the parameters.
  std::vector<Eigen::MatrixXd> sensitivities_at_phases;
  // Cubic (4-point Lagrange) interpolation from the n-point grid to the data phases: grid points
  // j0 - 1 .. j0 + 2 (mod n). Linear interpolation would bias the fit by h^2 y''/8, comparable to
  // the parameter uncertainty at n = 800.
  std::vector<int> j0;
  std::vector<std::array<double, 4>> weights;

  void MapPhases(int n) {
    j0.resize(data->phases.size());
    weights.resize(data->phases.size());
    for (std::size_t i = 0; i < data->phases.size(); ++i) {
      const double position = data->phases[i] * n;
      j0[i] = static_cast<int>(std::floor(position)) % n;
      const double t = position - std::floor(position);
      weights[i] = {-t * (t - 1) * (t - 2) / 6, (t + 1) * (t - 1) * (t - 2) / 2, -(t + 1) * t * (t - 2) / 2,
                    (t + 1) * t * (t - 1) / 6};
    }
  }
  //! A grid function (n values, any stride) at the data phases.
  template <class Grid>
  Eigen::VectorXd AtPhases(const Grid& grid) const {
    const int n = static_cast<int>(grid.size());
    Eigen::VectorXd out(j0.size());
    for (std::size_t i = 0; i < j0.size(); ++i) {
      double v = 0.0;
      for (int k = 0; k < 4; ++k) v += weights[i][k] * grid((j0[i] + k - 1 + n) % n);
      out[i] = v;
    }
    return out;
  }
  //! The transpose of AtPhases: values at the data phases spread back onto the n grid points.
  Eigen::VectorXd ToGrid(const Eigen::VectorXd& at_phases, int n) const {
    Eigen::VectorXd grid = Eigen::VectorXd::Zero(n);
    for (std::size_t i = 0; i < j0.size(); ++i)
      for (int k = 0; k < 4; ++k) grid[(j0[i] + k - 1 + n) % n] += weights[i][k] * at_phases[static_cast<int>(i)];
    return grid;
  }
  Eigen::VectorXd Residual(const std::string& channel, int row) const {
    return data->channels.at(channel).mean - AtPhases(solution.outputs.row(row));
  }
};

// Runs f(0) .. f(count - 1) on up to `threads` threads; the first exception is rethrown.
void ParallelFor(int count, int threads, const std::function<void(int)>& f) {
  threads = std::min(threads, count);
  if (threads <= 1) {
    for (int i = 0; i < count; ++i) f(i);
    return;
  }
  std::atomic<int> next{0};
  std::exception_ptr error;
  std::mutex error_mutex;
  const auto work = [&] {
    for (int i = next++; i < count; i = next++) {
      try {
        f(i);
      } catch (...) {
        const std::lock_guard lock(error_mutex);
        if (!error) error = std::current_exception();
      }
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t) pool.emplace_back(work);
  work();
  for (auto& t : pool) t.join();
  if (error) std::rethrow_exception(error);
}

struct Evaluation {
  bool ok = true;
  std::vector<double> sum_squares;  // per channel, over active experiments
  std::vector<long> counts;         // residuals per channel
};

}  // namespace

bool EstimatorOptions::IsValid(std::string* error) const {
  const auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (n < 8) return fail("n must be at least 8");
  if (max_iterations < 1) return fail("max_iterations must be at least 1");
  if (!(step_tolerance > 0)) return fail("step_tolerance must be positive");
  if (!(damping_relative_sd > 0)) return fail("damping_relative_sd must be positive");
  if (max_halvings < 0) return fail("max_halvings must not be negative");
  if (start_up_periods < 0) return fail("start_up_periods must not be negative");
  if (coarse_points < 0) return fail("coarse_points must not be negative");
  if (threads < 0) return fail("threads must not be negative");
  return true;
}

std::vector<ParameterChoice> DefaultChoices(const Model& model) {
  std::vector<ParameterChoice> choices(model.parameter_count());
  for (int i = 0; i < model.parameter_count(); ++i) choices[i].estimate = model.defaults().spec(i).estimate_by_default;
  return choices;
}

std::vector<ParameterChoice> ChoicesFromList(const ParameterSet& parameters, const std::string& list) {
  std::vector<ParameterChoice> choices(parameters.size());
  std::size_t start = 0;
  while (start <= list.size()) {
    const std::size_t comma = list.find(',', start);
    std::string item = list.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    item.erase(0, item.find_first_not_of(" \t"));
    item.erase(item.find_last_not_of(" \t") + 1);
    if (!item.empty()) choices[parameters.position(item)].estimate = true;
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return choices;
}

Estimator::Estimator(Model model, EstimatorOptions options) : model_(std::move(model)), options_(std::move(options)) {
  std::string error;
  if (!options_.IsValid(&error)) throw std::invalid_argument("estimator options: " + error);
}

FitSummary Estimator::Fit(const std::vector<ExperimentData>& data, const ParameterSet& initial,
                          const std::vector<ParameterChoice>& choices, const std::vector<DataIssue>& issues,
                          const std::function<void(const FitProgress&)>& progress) const {
  const int np = model_.parameter_count();
  if (initial.size() != np || static_cast<int>(choices.size()) != np)
    throw std::invalid_argument("estimator: parameter set and choices must match the model");
  const std::vector<std::string> channels = options_.channels.empty() ? DefaultChannels(model_) : options_.channels;
  const std::vector<std::string> outputs = model_.output_channels();
  std::vector<int> output_row;
  for (const auto& c : channels) {
    const auto it = std::find(outputs.begin(), outputs.end(), c);
    if (it == outputs.end())
      throw std::invalid_argument(fmt::format("estimator: model {} has no output '{}'", model_.composition(), c));
    output_row.push_back(static_cast<int>(it - outputs.begin()));
  }
  const int nc = static_cast<int>(channels.size());
  std::vector<int> est;
  for (int i = 0; i < np; ++i)
    if (choices[i].estimate) est.push_back(i);
  const int l = static_cast<int>(est.size());
  const int n = options_.n;

  FitSummary summary;
  summary.model = model_.composition();
  summary.parameters = initial;
  summary.estimated.assign(np, false);
  for (int i : est) summary.estimated[i] = true;
  summary.estimated_positions = est;

  // Experiments: solvers, defects, starting solutions.
  PeriodicSolverOptions solver_options;
  solver_options.scheme = options_.scheme;
  solver_options.start_up_periods = options_.start_up_periods;
  solver_options.coarse_points = options_.coarse_points;
  std::vector<ExperimentState> states;
  states.reserve(data.size());
  for (const ExperimentData& d : data) {
    ExperimentState s{&d,
                      options_.predictor ? options_.predictor(model_)
                                         : std::make_unique<PeriodicSolver>(model_, solver_options),
                      {},
                      true,
                      std::vector<bool>(nc, true),
                      {}};
    if (static_cast<int>(d.input.values.size()) != n)
      throw std::invalid_argument(fmt::format("estimator: experiment '{}' has {} grid points, the fit uses n = {}",
                                              d.label, d.input.values.size(), n));
    s.MapPhases(n);
    for (int b = 0; b < nc; ++b) {
      if (!d.channels.count(channels[b])) {
        s.channel_fitted[b] = false;
        summary.warnings.push_back(
            fmt::format("{}: experiment '{}' has no '{}' channel; left out of that channel", d.session, d.label, channels[b]));
      }
      for (const DataIssue& issue : issues)
        if (issue.experiment == d.label && issue.channel == channels[b] && s.channel_fitted[b]) {
          s.channel_fitted[b] = false;
          summary.warnings.push_back(fmt::format("experiment '{}', channel '{}': {} ({}); not fitted", d.label,
                                                 channels[b], issue.kind, issue.detail));
        }
    }
    states.push_back(std::move(s));
  }
  for (const DataIssue& issue : issues)
    if (std::find(channels.begin(), channels.end(), issue.channel) == channels.end())
      summary.warnings.push_back(fmt::format("experiment '{}', channel '{}': {} ({})", issue.experiment, issue.channel,
                                             issue.kind, issue.detail));

  std::vector<double> theta = initial.values();
  // Solves every active experiment at `values`; warm starts from `from` (the accepted iterate).
  const int threads = options_.threads > 0 ? options_.threads
                                           : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  // The first solve of an experiment (no warm start): from the measured stroke when that fits, else cold.
  const std::optional<Model> stroke_driven = StrokeDrivenTwin(model_);
  const auto first_solve = [&](const ExperimentState& s, const std::vector<double>& values) {
    const auto measured = stroke_driven ? MeasuredStrokeStart(model_, *stroke_driven, *s.data, values, n, solver_options)
                                        : std::nullopt;
    if (measured) {
      try {
        return s.solver->Solve(s.data->input, values, &*measured);
      } catch (const PeriodicSolverError& e) {
        spdlog::debug("experiment '{}': no solution from the measured stroke ({}); cold start", s.data->label,
                      e.what());
      }
    }
    return s.solver->Solve(s.data->input, values);
  };
  const auto solve_all = [&](const std::vector<double>& values, bool allow_drop, int iteration) {
    // Experiments are independent: solved on `threads` threads (progress is reported as they start).
    std::vector<std::optional<std::string>> failure(states.size());
    std::mutex progress_mutex;
    ParallelFor(static_cast<int>(states.size()), threads, [&](int a) {
      ExperimentState& s = states[a];
      if (!s.active) return;
      if (progress) {
        const std::lock_guard lock(progress_mutex);
        progress({iteration, a + 1, static_cast<int>(states.size()), NAN});
      }
      try {
        s.solution = s.solution.n == n ? s.solver->Solve(s.data->input, values, &s.solution) : first_solve(s, values);
      } catch (const PeriodicSolverError& e) {
        failure[a] = e.what();
      }
    });
    bool ok = true;
    for (std::size_t a = 0; a < states.size(); ++a) {
      if (!failure[a]) continue;
      if (!allow_drop) return false;
      ExperimentState& s = states[a];
      s.active = false;
      s.dropped_at_start = true;
      s.error = *failure[a];
      spdlog::warn("experiment '{}': no periodic solution at the starting values ({}); left out until the "
                   "parameters improve",
                   s.data->label, s.error);
      ok = false;
    }
    return ok || allow_drop;
  };
  const auto evaluate = [&]() {
    Evaluation e;
    e.sum_squares.assign(nc, 0.0);
    e.counts.assign(nc, 0);
    for (const ExperimentState& s : states) {
      if (!s.active) continue;
      for (int b = 0; b < nc; ++b) {
        if (!s.channel_fitted[b]) continue;
        const Eigen::VectorXd r = s.Residual(channels[b], output_row[b]);
        e.sum_squares[b] += r.squaredNorm();
        e.counts[b] += r.size();
      }
    }
    for (double v : e.sum_squares) e.ok = e.ok && std::isfinite(v);
    return e;
  };
  // Log-likelihood with the channel variances at their maximum-likelihood values.
  const auto loglik = [&](const Evaluation& e) {
    double value = 0.0;
    for (int b = 0; b < nc; ++b)
      if (e.counts[b] > 0)
        value -= 0.5 * e.counts[b] * (std::log(2 * std::numbers::pi * std::max(e.sum_squares[b] / e.counts[b], 1e-300)) + 1.0);
    return value;
  };
  // Prior term of the user's priors (mean: the initial value).
  const auto prior_term = [&](const std::vector<double>& values) {
    double value = 0.0;
    for (int i : est)
      if (choices[i].prior_sd) value -= 0.5 * std::pow((values[i] - initial.value(i)) / *choices[i].prior_sd, 2);
    return value;
  };

  solve_all(theta, true, 0);
  if (std::none_of(states.begin(), states.end(), [](const ExperimentState& s) { return s.active; }))
    throw std::runtime_error("estimator: no experiment has a periodic solution at the starting values");
  Evaluation current = evaluate();
  double objective = loglik(current) + prior_term(theta);
  summary.history.push_back({0, objective, 0.0, theta});

  // Scales: work in theta_i / scale_i so the normal equations are well conditioned.
  std::vector<double> scale(np);
  for (int i = 0; i < np; ++i) scale[i] = std::max({std::abs(theta[i]), initial.spec(i).typical_size(), 1e-300});
  double damping_sd = options_.damping_relative_sd;
  Eigen::MatrixXd information(l, l);
  Eigen::VectorXd step_sd = Eigen::VectorXd::Constant(l, INFINITY);

  // The staged Gauss-Newton iteration of eqs. 18, 19.
  // With `input_noise`: also, per experiment, the scaled-gradient covariance that the measured
  // input's noise causes (sum over its noisy Fourier coefficients of var * q q^T, q = J^T W dy/dc).
  // Steps may use sensitivities within a few percent (the solution's carried factorisation, as the
  // paper reuses the last one); the final uncertainty (`input_noise` given) takes exact ones.
  // `reuse`: the experiments' sensitivities of the previous call where they have them.
  const auto normal_equations = [&](const std::vector<double>& variance, Eigen::MatrixXd& h, Eigen::VectorXd& g,
                                    Eigen::MatrixXd* input_noise = nullptr, bool exact = false, bool reuse = false) {
    h.setZero(l, l);
    g.setZero(l);
    // Per experiment on `threads` threads, summed in experiment order (the same result for any count).
    std::vector<Eigen::MatrixXd> hs(states.size(), Eigen::MatrixXd::Zero(l, l));
    std::vector<Eigen::VectorXd> gs(states.size(), Eigen::VectorXd::Zero(l));
    std::vector<Eigen::MatrixXd> ns(states.size(), Eigen::MatrixXd::Zero(l, l));
    ParallelFor(static_cast<int>(states.size()), threads, [&](int a) {
      ExperimentState& s = states[a];
      if (!s.active) return;
      if (!reuse || static_cast<int>(s.sensitivities_at_phases.size()) != nc) {
        const auto sens = s.solver->OutputSensitivities(s.solution, theta, est, exact);
        s.sensitivities_at_phases.assign(nc, Eigen::MatrixXd());
        for (int b = 0; b < nc; ++b) {
          if (!s.channel_fitted[b]) continue;
          Eigen::MatrixXd& j = s.sensitivities_at_phases[b];
          j.resize(static_cast<Eigen::Index>(s.j0.size()), l);
          for (int k = 0; k < l; ++k) j.col(k) = s.AtPhases(sens[output_row[b]].col(k)) * scale[est[k]];
        }
      }
      // The gradient's noise from the input's: J^T W P dy = (P^T W J)^T dy on the grid (P the
      // interpolation to the phases), so the output weights P^T W J give it by one adjoint solve.
      const bool with_input = input_noise && s.data->input_harmonic_variance > 0;
      std::vector<Eigen::MatrixXd> weights;
      if (with_input) weights.assign(s.solution.channels.size(), Eigen::MatrixXd::Zero(n, l));
      for (int b = 0; b < nc; ++b) {
        if (!s.channel_fitted[b]) continue;
        const Eigen::MatrixXd& j = s.sensitivities_at_phases[b];
        const Eigen::VectorXd r = s.Residual(channels[b], output_row[b]);
        hs[a].noalias() += j.transpose() * j / variance[b];
        gs[a].noalias() += j.transpose() * r / variance[b];
        if (with_input)
          for (int k = 0; k < l; ++k) weights[output_row[b]].col(k) += s.ToGrid(j.col(k), n) / variance[b];
      }
      if (with_input) {
        const Eigen::MatrixXd gradient = s.solver->InputGradients(s.solution, theta, weights);
        if (gradient.size() > 0) ns[a] = InputNoiseCovariance(*s.data, gradient);
      }
    });
    for (std::size_t a = 0; a < states.size(); ++a) {
      h += hs[a];
      g += gs[a];
    }
    if (input_noise) {
      input_noise->setZero(l, l);
      for (const auto& m_a : ns) *input_noise += m_a;
    }
    for (int k = 0; k < l; ++k) {
      const int i = est[k];
      if (choices[i].prior_sd) {
        const double w = std::pow(*choices[i].prior_sd / scale[i], 2);
        h(k, k) += 1.0 / w;
        g[k] -= (theta[i] - initial.value(i)) / scale[i] / w;
      }
    }
  };

  std::vector<double> variance(nc);
  int iteration = 0;
  bool converged = l == 0;
  // Frozen sensitivities (modified Gauss-Newton): they change with the parameters relative to their
  // size, so after a step below this fraction of every parameter (scaled units) they are within
  // about that fraction, inside the few percent the steps tolerate.
  constexpr double kFrozenSensitivityStep = 0.01;
  bool reuse_sensitivities = false;
  for (; iteration < options_.max_iterations && !converged; ++iteration) {
    // Stage 1 (eq. 18): channel variances with bias correction.
    for (int b = 0; b < nc; ++b)
      variance[b] = std::max(current.sum_squares[b] / std::max(1.0, double(current.counts[b] - l)), 1e-300);
    // Stage 2 (eq. 19): parameter update with the prior reset to the current iterate.
    Eigen::VectorXd g;
    normal_equations(variance, information, g, nullptr, false, reuse_sensitivities);
    Eigen::MatrixXd damped = information;
    for (int k = 0; k < l; ++k) damped(k, k) += 1.0 / (damping_sd * damping_sd);
    const Eigen::VectorXd step = damped.ldlt().solve(g);
    if (!step.allFinite()) {
      summary.warnings.push_back("estimator: the normal equations became singular; stopped");
      break;
    }
    const Eigen::MatrixXd covariance = information.ldlt().solve(Eigen::MatrixXd::Identity(l, l));
    for (int k = 0; k < l; ++k) step_sd[k] = std::sqrt(std::max(covariance(k, k), 0.0));
    // At the optimum to the tolerance already: the step needs no trial solves (at the optimum the
    // line search could only halve through rounding, one round of solves per halving).
    if ((step.array().abs() / step_sd.array()).maxCoeff() < options_.step_tolerance) {
      converged = true;
      break;
    }

    // Line search: halve until the objective improves.
    double lambda = 1.0;
    bool accepted = false;
    std::vector<double> trial(theta);
    for (int halving = 0; halving <= options_.max_halvings; ++halving, lambda *= 0.5) {
      for (int k = 0; k < l; ++k) trial[est[k]] = theta[est[k]] + lambda * step[k] * scale[est[k]];
      const std::vector<PeriodicSolution> saved = [&] {
        std::vector<PeriodicSolution> v;
        for (const auto& s : states) v.push_back(s.solution);
        return v;
      }();
      if (solve_all(trial, false, iteration + 1)) {
        const Evaluation e = evaluate();
        const double value = loglik(e) + prior_term(trial);
        if (e.ok && value >= objective - 1e-12 * std::abs(objective)) {
          theta = trial;
          current = e;
          const double gain = value - objective;
          objective = value;
          accepted = true;
          spdlog::debug("fit iteration {}: loglik {:.6g} (+{:.3g}), step {}, damping sd {:.3g}, steps in scales{}",
                        iteration + 1, objective, gain, lambda, damping_sd, [&] {
                          std::string s;
                          for (int k = 0; k < l; ++k) s += fmt::format(" {:.3g}", lambda * step[k]);
                          return s;
                        }());
          break;
        }
      }
      for (std::size_t a = 0; a < states.size(); ++a) states[a].solution = saved[a];
    }
    if (progress) progress({iteration + 1, 0, static_cast<int>(states.size()), objective});
    summary.history.push_back({iteration + 1, objective, accepted ? lambda : 0.0, theta});
    if (!accepted) {
      // No improvement along the damped step: at the optimum to the accuracy the solutions allow.
      converged = (step.array().abs() / step_sd.array()).maxCoeff() < 0.1;
      if (!converged) summary.warnings.push_back("estimator: no improvement along the Gauss-Newton step; stopped");
      break;
    }
    // Experiments without a solution at the start may have one now: bring them back in.
    bool readmitted = false;
    for (ExperimentState& s : states) {
      if (s.active || !s.dropped_at_start) continue;
      try {
        s.solution = first_solve(s, theta);
        s.active = true;
        s.error.clear();
        readmitted = true;
        spdlog::info("experiment '{}' has a periodic solution again; back in the fit", s.data->label);
      } catch (const PeriodicSolverError&) {
      }
    }
    if (readmitted) {
      current = evaluate();
      objective = loglik(current) + prior_term(theta);
      summary.history.back().objective = objective;
      converged = false;
      reuse_sensitivities = false;
      damping_sd = std::max(damping_sd * 0.25, 1e-6);
      continue;
    }
    damping_sd = lambda == 1.0 ? std::min(damping_sd * 2.0, 1e3) : std::max(damping_sd * 0.25, 1e-6);
    const double step_in_sd = (lambda * step.array().abs() / step_sd.array()).maxCoeff();
    converged = step_in_sd < options_.step_tolerance;
    reuse_sensitivities = (lambda * step.array().abs()).maxCoeff() < kFrozenSensitivityStep;
  }
  summary.converged = converged;
  summary.iterations = iteration;
  summary.parameters.values() = theta;

  // Uncertainty at the final iterate: posterior covariance without the damping prior.
  const long total = std::accumulate(current.counts.begin(), current.counts.end(), 0L);
  for (int b = 0; b < nc; ++b)
    variance[b] = std::max(current.sum_squares[b] / std::max(1.0, double(current.counts[b] - l)), 1e-300);
  summary.sd.assign(np, NAN);
  if (l > 0) {
    Eigen::VectorXd g;
    Eigen::MatrixXd input_noise;
    normal_equations(variance, information, g, options_.input_noise ? &input_noise : nullptr, true);
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(information);
    const double largest = eig.eigenvalues().maxCoeff();
    Eigen::MatrixXd covariance = information.completeOrthogonalDecomposition().pseudoInverse();
    if (options_.input_noise && input_noise.size() > 0 && input_noise.allFinite()) {
      // Errors in variables: the measured input's noise moves the estimate by H^-1 J^T W dy; its
      // covariance (the sandwich H^-1 N H^-1) adds to the output-noise part H^-1.
      const Eigen::MatrixXd extra = covariance * input_noise * covariance;
      Eigen::VectorXd share(l);
      for (int a = 0; a < l; ++a) share[a] = std::sqrt(1.0 + extra(a, a) / std::max(covariance(a, a), 1e-300));
      covariance += extra;
      summary.input_noise_sd_factor.assign(np, NAN);
      for (int a = 0; a < l; ++a) summary.input_noise_sd_factor[est[a]] = share[a];
    }
    summary.correlation.resize(l, l);
    for (int a = 0; a < l; ++a) {
      summary.sd[est[a]] = std::sqrt(std::max(covariance(a, a), 0.0)) * scale[est[a]];
      for (int b = 0; b < l; ++b)
        summary.correlation(a, b) = covariance(a, b) / std::sqrt(std::max(covariance(a, a) * covariance(b, b), 1e-300));
    }
    // Parameters the data cannot determine: a near-null direction of the information matrix.
    for (int k = 0; k < l; ++k) {
      if (eig.eigenvalues()[k] > 1e-10 * largest) continue;
      std::string names;
      for (int a = 0; a < l; ++a)
        if (std::abs(eig.eigenvectors()(a, k)) > 0.3) names += " " + initial.spec(est[a]).key();
      summary.warnings.push_back(fmt::format("the data cannot determine{} (near-singular information matrix); fix "
                                             "one of them or add experiments",
                                             names));
    }
    for (int a = 0; a < l; ++a)
      for (int b = a + 1; b < l; ++b)
        if (std::abs(summary.correlation(a, b)) > 0.99)
          summary.warnings.push_back(fmt::format("{} and {} are correlated {:.3f}: the data barely tell them apart",
                                                 initial.spec(est[a]).key(), initial.spec(est[b]).key(),
                                                 summary.correlation(a, b)));
  }

  // Statistics per channel and per experiment.
  summary.observations = total;
  summary.loglik = loglik(current);
  summary.aic = -2.0 * summary.loglik + 2.0 * l;
  summary.bic = -2.0 * summary.loglik + l * std::log(static_cast<double>(std::max(1L, total)));
  for (int b = 0; b < nc; ++b) {
    FitChannel c;
    c.name = channels[b];
    c.variance = variance[b];
    c.rms = current.counts[b] > 0 ? std::sqrt(current.sum_squares[b] / current.counts[b]) : NAN;
    double noise = 0.0;
    int count = 0;
    for (const ExperimentState& s : states) {
      const auto it = s.data->channels.find(channels[b]);
      if (s.active && s.channel_fitted[b] && it != s.data->channels.end() && std::isfinite(it->second.mean_noise_variance)) {
        noise += it->second.mean_noise_variance;
        ++count;
      }
    }
    c.noise_floor_variance = count > 0 ? noise / count : NAN;
    summary.channels.push_back(c);
  }
  for (ExperimentState& s : states) {
    ExperimentFit f;
    f.label = s.data->label;
    f.group = s.data->group;
    f.session = s.data->session;
    f.frequency = s.data->frequency;
    f.amplitude = s.data->amplitude;
    f.static_position = s.data->static_position;
    f.converged = s.active;
    f.error = s.error;
    f.phases = s.data->phases;
    for (const auto& [name, channel] : s.data->channels) f.measured[name] = channel.mean;
    if (!s.active)
      summary.warnings.push_back(fmt::format("experiment '{}': no periodic solution ({}); left out of the fit",
                                             s.data->label, s.error));
    for (int b = 0; b < nc; ++b) {
      ChannelStatistics st;
      st.channel = channels[b];
      st.fitted = s.channel_fitted[b] && s.active;
      const auto it = s.data->channels.find(channels[b]);
      if (s.active && it != s.data->channels.end()) {
        const Eigen::VectorXd r = s.Residual(channels[b], output_row[b]);
        f.residual[channels[b]] = r;
        f.noise_variance[channels[b]] = it->second.mean_noise_variance;
        st.mean = r.mean();
        st.sd = std::sqrt((r.array() - st.mean).square().sum() / std::max<Eigen::Index>(1, r.size() - 1));
        st.rms = std::sqrt(r.squaredNorm() / r.size());
        st.noise_ratio = st.rms * st.rms / it->second.mean_noise_variance;
      }
      f.channels.push_back(st);
    }
    if (s.active) f.solution = std::move(s.solution);
    summary.experiments.push_back(std::move(f));
  }
  if (!summary.converged && summary.warnings.empty())
    summary.warnings.push_back(fmt::format("estimator: not converged after {} iterations", iteration));
  return summary;
}

bool FitSummary::IsSolutionUsable() const {
  return std::any_of(experiments.begin(), experiments.end(), [](const ExperimentFit& e) { return e.converged; }) &&
         std::isfinite(loglik);
}

std::string FitSummary::BriefReport() const {
  return fmt::format("{}: {} after {} iterations, loglik {:.6g}, BIC {:.6g}, {} warnings", model,
                     converged ? "converged" : "NOT converged", iterations, loglik, bic, warnings.size());
}

std::string FitSummary::FullReport() const {
  std::string out = BriefReport() + "\n\nparameters:\n";
  for (int i = 0; i < parameters.size(); ++i) {
    const auto& spec = parameters.spec(i);
    out += fmt::format("  {:<8} {:<28} {:>14.7g} {:<10} {}\n", spec.key(), spec.name, parameters.value(i), spec.unit,
                       estimated[i] ? fmt::format("+- {:.3g} (estimated)", sd[i]) : std::string("(fixed)"));
  }
  out += "\nchannels:\n";
  for (const auto& c : channels)
    out += fmt::format("  {:<12} rms {:.4g}  variance {:.4g}  noise floor {:.4g}\n", c.name, c.rms, c.variance,
                       c.noise_floor_variance);
  out += "\nexperiments (residual mean / 2 sd / noise ratio per channel):\n";
  for (const auto& e : experiments) {
    out += fmt::format("  {:<6} {:<7} {:5.2f} Hz", e.label, e.group, e.frequency);
    if (!e.converged) {
      out += "  no periodic solution: " + e.error + "\n";
      continue;
    }
    for (const auto& c : e.channels)
      out += fmt::format("  {}: {:+.3g} / {:.3g} / {:.3g}{}", c.channel, c.mean, 2 * c.sd, c.noise_ratio,
                         c.fitted ? "" : " (not fitted)");
    out += "\n";
  }
  for (const auto& w : warnings) out += "warning: " + w + "\n";
  return out;
}

}  // namespace strut::ident
