#include "strut/ident/estimator.h"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <numeric>
#include <spdlog/spdlog.h>

#include "strut/ident/bard.h"
#include "strut/ident/fit_problem.h"

namespace strut::ident {

bool EstimatorOptions::IsValid(std::string* error) const {
  const auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (n != 0 && n < 8) return fail("n must be 0 (by causality) or at least 8");
  if (max_iterations < 1) return fail("max_iterations must be at least 1");
  if (!(step_tolerance > 0)) return fail("step_tolerance must be positive");
  if (!(damping_relative_sd > 0)) return fail("damping_relative_sd must be positive");
  if (max_halvings < 0) return fail("max_halvings must not be negative");
  if (start_up_periods < 0) return fail("start_up_periods must not be negative");
  if (coarse_points < 0) return fail("coarse_points must not be negative");
  if (threads < 0) return fail("threads must not be negative");
  if (input_harmonics < 0) return fail("input_harmonics must not be negative");
  return true;
}

namespace {

//! Estimated with the spec's default prior, if it has one.
ParameterChoice Estimated(const ParameterSpec& spec) {
  ParameterChoice c;
  c.estimate = true;
  if (spec.prior_sd > 0) c.prior_sd = spec.prior_sd;
  return c;
}

//! What each experiment adds (ExperimentContribution): its share of the information's diagonal and
//! the posterior sd with it left out (its information, input noise and estimated input removed).
std::vector<ExperimentContribution> Contributions(const std::vector<std::pair<std::string, std::string>>& labels,
                                                  const NormalEquations& eq, const ScaledPriors& priors,
                                                  const std::vector<int>& est, const std::vector<double>& scale, int np) {
  std::vector<ExperimentContribution> out;
  const int l = static_cast<int>(est.size());
  if (eq.experiment_information.size() != labels.size()) return out;
  const Eigen::VectorXd diagonal = eq.information.diagonal();
  for (std::size_t a = 0; a < labels.size(); ++a) {
    ExperimentContribution c;
    c.label = labels[a].first;
    c.kind = labels[a].second;
    c.information_share.assign(np, NAN);
    c.sd_without.assign(np, NAN);
    const Eigen::MatrixXd& h = eq.experiment_information[a];
    const Eigen::MatrixXd noise = eq.input_noise.size() > 0 && a < eq.experiment_input_noise.size()
                                      ? Eigen::MatrixXd(eq.input_noise - eq.experiment_input_noise[a])
                                      : eq.input_noise;
    std::vector<NuisanceBlock> inputs = eq.inputs;
    if (a < inputs.size()) inputs[a] = NuisanceBlock();
    const Posterior without = PosteriorCovariance(eq.information - h, noise, priors, inputs);
    std::vector<bool> undetermined(l, false);
    for (const auto& direction : without.undetermined)
      for (int k : direction) undetermined[k] = true;
    for (int k = 0; k < l; ++k) {
      c.information_share[est[k]] = diagonal[k] > 0 ? h(k, k) / diagonal[k] : NAN;
      c.sd_without[est[k]] =
          undetermined[k] ? INFINITY : std::sqrt(std::max(without.covariance(k, k), 0.0)) * scale[est[k]];
    }
    out.push_back(std::move(c));
  }
  return out;
}

}  // namespace

std::vector<ParameterChoice> DefaultChoices(const ParameterSet& parameters) {
  std::vector<ParameterChoice> choices(parameters.size());
  for (int i = 0; i < parameters.size(); ++i) {
    const ParameterSpec& spec = parameters.spec(i);
    if (spec.estimate_by_default || spec.estimated_with_term()) choices[i] = Estimated(spec);
  }
  return choices;
}

std::vector<ParameterChoice> DefaultChoices(const Model& model) { return DefaultChoices(model.defaults()); }

std::vector<ParameterChoice> PaperChoices(const ParameterSet& parameters) {
  std::vector<ParameterChoice> choices(parameters.size());
  for (int i = 0; i < parameters.size(); ++i) {
    const ParameterSpec& spec = parameters.spec(i);
    const bool paper = spec.index == 4 || spec.index == 6 || spec.index == 16 || spec.index == 11 ||
                       spec.index == 12 || spec.name == "polytropic_exponent";
    // Models that are not dampers (linear-oscillator, index 50 on) have no paper set: their defaults.
    if (paper || (spec.index >= 50 && spec.estimate_by_default)) choices[i] = Estimated(spec);
  }
  return choices;
}

std::vector<ParameterChoice> ChoicesFromList(const ParameterSet& parameters, const std::string& list) {
  std::string trimmed = list;
  trimmed.erase(0, trimmed.find_first_not_of(" \t"));
  trimmed.erase(trimmed.find_last_not_of(" \t") + 1);
  if (trimmed == "paper") return PaperChoices(parameters);
  if (trimmed.empty() || trimmed == "default") return DefaultChoices(parameters);
  std::vector<ParameterChoice> choices(parameters.size());
  std::size_t start = 0;
  while (start <= list.size()) {
    const std::size_t comma = list.find(',', start);
    std::string item = list.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    item.erase(0, item.find_first_not_of(" \t"));
    item.erase(item.find_last_not_of(" \t") + 1);
    if (!item.empty()) {
      const int i = parameters.position(item);
      choices[i] = Estimated(parameters.spec(i));
    }
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
                          const std::function<void(const FitProgress&)>& progress,
                          const std::vector<TransientExperimentData>& transients) const {
  const int np = model_.parameter_count();
  if (initial.size() != np || static_cast<int>(choices.size()) != np)
    throw std::invalid_argument("estimator: parameter set and choices must match the model");
  std::vector<int> est;
  for (int i = 0; i < np; ++i)
    if (choices[i].estimate) est.push_back(i);
  const int l = static_cast<int>(est.size());

  FitSummary summary;
  summary.model = model_.composition();
  summary.parameters = initial;
  summary.estimated.assign(np, false);
  for (int i : est) summary.estimated[i] = true;
  summary.estimated_positions = est;

  std::vector<double> theta = initial.values();
  // Scales: work in theta_i / scale_i so the normal equations are well conditioned.
  std::vector<double> scale(np);
  for (int i = 0; i < np; ++i) scale[i] = std::max({std::abs(theta[i]), initial.spec(i).typical_size(), 1e-300});
  const auto scaled = [&](const std::vector<double>& values) {
    Eigen::VectorXd x(l);
    for (int k = 0; k < l; ++k) x[k] = values[est[k]] / scale[est[k]];
    return x;
  };
  const auto unscaled = [&](const Eigen::VectorXd& x) {
    std::vector<double> values = theta;
    for (int k = 0; k < l; ++k) values[est[k]] = x[k] * scale[est[k]];
    return values;
  };
  // The user's priors (mean: the starting value) and the parameters' physical ranges (the
  // iterates stay inside them: the line search's trials are projected), scaled.
  ScaledPriors priors{Eigen::VectorXd::Zero(l), scaled(initial.values())};
  ScaledBounds bounds{Eigen::VectorXd::Constant(l, -INFINITY), Eigen::VectorXd::Constant(l, INFINITY)};
  for (int k = 0; k < l; ++k) {
    const int i = est[k];
    if (choices[i].prior_sd) priors.precision[k] = std::pow(scale[i] / *choices[i].prior_sd, 2);
    // Open ends (a mass > 0) keep a millionth of the parameter's scale inside them.
    const PhysicalRange& range = initial.spec(i).range;
    bounds.lower[k] = (range.lower + (range.lower_open ? 1e-6 * scale[i] : 0.0)) / scale[i];
    bounds.upper[k] = (range.upper - (range.upper_open ? 1e-6 * scale[i] : 0.0)) / scale[i];
  }

  FitProblem problem(model_, options_, data, issues, est, scale, transients);
  summary.warnings = problem.warnings();
  problem.Solve(theta, true, 0, progress);
  if (problem.active_count() == 0)
    throw std::runtime_error("estimator: no experiment has a solution at the starting values");
  Eigen::VectorXd x = scaled(theta);
  ResidualSums current = problem.Evaluate();
  // With estimated inputs (errors in variables) the objective also has their prior.
  double objective = current.LogLikelihood() + priors.LogDensity(x) + problem.InputLogPrior();
  summary.history.push_back({0, objective, 0.0, theta});

  // The staged Gauss-Newton iteration of eqs. 18, 19.
  double damping_sd = options_.damping_relative_sd;
  int iteration = 0;
  bool converged = l == 0;
  // Frozen sensitivities (modified Gauss-Newton): they change with the parameters relative to their
  // size, so after a step below this fraction of every parameter (scaled units) they are within
  // about that fraction, inside the few percent the steps tolerate.
  constexpr double kFrozenSensitivityStep = 0.01;
  constexpr double kFrozenInputStep = 0.1;
  // Estimated inputs converge when their steps are below this fraction of their sd (given the
  // parameters): the parameters' step allows for the inputs' pending one (Schur complement), so the
  // inputs' tolerance only sets how close the residuals are to their optimum.
  constexpr double kInputStepTolerance = 0.1;
  constexpr double kJoinInputsInSd = 0.1;
  bool reuse_sensitivities = false;
  // Errors in variables (estimated inputs) in two rounds: the parameters first with every input at its
  // thresholded series, then parameters and inputs together from there. Far from the optimum the
  // inputs would take up the model's misfit (from 20 % off the friction's sign flipped through
  // sharpness 0 on the standard matrix), near it they take up what the series truncates.
  bool estimating_inputs = false;
  // At an iterate within reach of the first round's optimum: true when the fit goes on with the inputs estimated.
  // `sensitivities_current`: the last Linearise was at this iterate, so the joint problem's first one
  // keeps its parameter sensitivities and adds the inputs'.
  const auto estimate_inputs_now = [&](bool sensitivities_current) {
    if (estimating_inputs || !problem.estimates_inputs()) return false;
    spdlog::debug("fit iteration {}: within reach with the measured inputs; now estimating them too", iteration + 1);
    estimating_inputs = true;
    reuse_sensitivities = sensitivities_current;
    // From the optimum with the measured inputs the joint problem starts within its Gauss-Newton range:
    // almost undamped (sd 30 in scaled units and in the inputs' prior sd; the line search still halves).
    // Reset to 0.3, the damping held the inputs' first steps to a tenth and took 7 iterations from
    // the truth on the standard matrix where this takes 4.
    damping_sd = std::max(damping_sd, 100.0 * options_.damping_relative_sd);
    return true;
  };
  for (; iteration < options_.max_iterations && !converged; ++iteration) {
    // Stage 1 (eq. 18): channel variances with bias correction; stage 2 (eq. 19): the step.
    const NormalEquations eq =
        problem.Linearise(theta, current.Variances(l), {false, reuse_sensitivities, false, estimating_inputs});
    const BardStep step = ComputeBardStep(eq.information, eq.gradient, x, priors, bounds, damping_sd, eq.inputs);
    if (!step.finite) {
      summary.warnings.push_back("estimator: the normal equations became singular; stopped");
      break;
    }
    // At the optimum to the tolerance already (the undamped step: a damped one can be tiny far from
    // the optimum, in a narrow valley): no trial solves (at the optimum the line search could only
    // halve through rounding, one round of solves per halving).
    if (step.NewtonInSd() < options_.step_tolerance && step.nuisance_step_in_sd < kInputStepTolerance) {
      if (estimate_inputs_now(true)) continue;
      converged = true;
      break;
    }
    // The first round only has to bring the joint problem within its Gauss-Newton range: within a
    // tenth of an sd of the first round's optimum (the joint optimum lies 0.3-1.7 sd from it on drawn
    // units) the inputs join at once instead of after the first round has converged to 1e-3 sd. At
    // 1 sd one drawn unit's restart from 30 % off ended in a neighbouring optimum of the joint
    // problem (0.28 sd apart along theta1-theta11, 0.06 lower in log-likelihood).
    if (!estimating_inputs && step.NewtonInSd() < kJoinInputsInSd && estimate_inputs_now(true)) continue;
    // Line search: halve until the objective improves (the trial kept inside the physical ranges).
    double lambda = 1.0;
    bool accepted = false;
    Eigen::VectorXd taken;
    double gain = 0.0;
    for (int halving = 0; halving <= options_.max_halvings; ++halving, lambda *= 0.5) {
      const Eigen::VectorXd trial_x = bounds.Project(x + lambda * step.step);
      const std::vector<double> trial = unscaled(trial_x);
      FitProblem::Saved saved = problem.Snapshot();
      problem.StepInputs(step.nuisance_step, lambda);
      if (problem.Solve(trial, false, iteration + 1, progress)) {
        const ResidualSums e = problem.Evaluate();
        const double value = e.LogLikelihood() + priors.LogDensity(trial_x) + problem.InputLogPrior();
        if (e.finite && value >= objective - 1e-12 * std::abs(objective)) {
          taken = trial_x - x;
          gain = value - objective;
          spdlog::debug("fit iteration {}: loglik {:.6g} (+{:.3g}), step {}, damping sd {:.3g}, undamped step {:.3g} sd{}",
                        iteration + 1, value, value - objective, lambda, damping_sd, step.NewtonInSd(),
                        estimating_inputs ? fmt::format(", input step {:.3g} sd", step.nuisance_step_in_sd) : "");
          theta = trial;
          x = trial_x;
          current = e;
          objective = value;
          accepted = true;
          break;
        }
      }
      problem.Restore(std::move(saved));
    }
    if (progress) progress({iteration + 1, 0, problem.experiment_count(), objective});
    summary.history.push_back({iteration + 1, objective, accepted ? lambda : 0.0, theta});
    if (!accepted) {
      // No improvement along the damped step: at the optimum to the accuracy the solutions allow.
      converged = step.NewtonInSd() < 0.1;
      if (converged && estimate_inputs_now(false)) {
        converged = false;
        continue;
      }
      if (!converged) summary.warnings.push_back("estimator: no improvement along the Gauss-Newton step; stopped");
      break;
    }
    // Experiments without a solution at the start may have one now: bring them back in.
    if (problem.Readmit(theta)) {
      current = problem.Evaluate();
      objective = current.LogLikelihood() + priors.LogDensity(x) + problem.InputLogPrior();
      summary.history.back().objective = objective;
      reuse_sensitivities = false;
      damping_sd = std::max(damping_sd * 0.25, 1e-6);
      continue;
    }
    damping_sd = lambda == 1.0 ? std::min(damping_sd * 2.0, 1e3) : std::max(damping_sd * 0.25, 1e-6);
    // At the rounding floor: the objective no longer changes beyond rounding (1e-10 of itself: the
    // residual sums of tens of thousands of samples carry about that) while the undamped step is
    // within a tenth of an sd. The sensitivities' accuracy, not the optimum, then limits the step,
    // and the line search would go on accepting steps that change nothing.
    if (std::abs(gain) < 1e-10 * std::abs(objective) && step.NewtonInSd() < 0.1) {
      if (estimate_inputs_now(false)) continue;
      converged = true;
      spdlog::debug("fit converged at the rounding floor (gain {:.3g}, undamped step {:.3g} sd)", gain, step.NewtonInSd());
      break;
    }
    // Otherwise convergence is judged at the top of the next iteration, on its undamped step. An estimated
    // input moves the reversals, where the friction makes the sensitivities change fastest: frozen
    // only after input steps below a tenth of their sd too.
    reuse_sensitivities = taken.cwiseAbs().maxCoeff() < kFrozenSensitivityStep &&
                          lambda * step.nuisance_step_in_sd < kFrozenInputStep;
  }
  summary.converged = converged;
  summary.iterations = iteration;
  summary.parameters.values() = theta;

  // Uncertainty at the final iterate: posterior covariance without the damping prior, with exact
  // sensitivities and the measured inputs' noise.
  const std::vector<double> variance = current.Variances(l);
  const std::vector<double> ratios = problem.NoiseRatios();
  summary.sd.assign(np, NAN);
  if (l > 0 && options_.uncertainty) {
    const NormalEquations eq = problem.Linearise(theta, variance, {true, false, options_.input_noise, estimating_inputs});
    const Posterior posterior = PosteriorCovariance(eq.information, eq.input_noise, priors, eq.inputs);
    Eigen::MatrixXd covariance = posterior.covariance;
    // Honest intervals above the noise floor: residuals of a model that lacks physics are
    // systematic, not white, and the covariance above (white noise at the residual variance) is
    // then far too narrow. Each parameter's sd is widened to what the experiments' disagreement
    // implies (the sandwich over experiments) where that is larger.
    const bool above_floor = std::any_of(ratios.begin(), ratios.end(), [](double r) { return r >= kNoiseFloorRatio; });
    if (above_floor) {
      const Eigen::MatrixXd robust = ExperimentSandwich(posterior.covariance, eq.experiment_gradient);
      summary.misfit_sd_factor.assign(np, NAN);
      double widest = 1.0;
      for (int a = 0; a < l; ++a) {
        const double factor = std::sqrt(std::max(1.0, robust(a, a) / std::max(covariance(a, a), 1e-300)));
        summary.misfit_sd_factor[est[a]] = factor;
        widest = std::max(widest, factor);
      }
      // Widen whole rows and columns, keeping the correlations of the white-noise covariance.
      for (int a = 0; a < l; ++a)
        for (int b = 0; b < l; ++b) covariance(a, b) *= summary.misfit_sd_factor[est[a]] * summary.misfit_sd_factor[est[b]];
      std::string channels;
      for (std::size_t b = 0; b < ratios.size(); ++b)
        channels += fmt::format("{}{} {:.3g}", channels.empty() ? "" : ", ", problem.channels()[b], ratios[b]);
      summary.warnings.push_back(fmt::format(
          "above the noise floor (residual over noise variance: {}): the intervals are widened by up to {:.3g} times "
          "for what the experiments disagree on (sandwich over experiments); a model that lacks physics is biased "
          "beyond any interval",
          channels, widest));
    }
    // Transducer calibration (EstimatorOptions::gain_sd): a channel reading (1 + g) times the truth
    // moves the estimate by g v, v = H^-1 d(J^T W e)/dg (an output's residuals gain g y, the input's
    // gain moves every output along the input; the estimated inputs eliminated as in the Bard
    // step); a gain known to sd s adds s^2 v v^T to the covariance.
    if (!options_.gain_sd.empty()) {
      Eigen::MatrixXd calibration = Eigen::MatrixXd::Zero(l, l);
      Eigen::MatrixXd information = eq.information;  // with the priors, as in the posterior
      information.diagonal() += priors.precision;
      for (const auto& [channel, gain_sd] : options_.gain_sd) {
        if (!(gain_sd > 0)) continue;
        const FitProblem::GainGradient gain = problem.GainGradients(channel, theta, variance);
        if (!gain.covered) continue;  // not in these data
        Eigen::MatrixXd h = information;  // EliminateNuisance reduces it in place
        Eigen::VectorXd g = gain.parameters;
        std::vector<NuisanceBlock> inputs = eq.inputs;
        for (std::size_t a = 0; a < inputs.size(); ++a)
          if (!inputs[a].empty())
            inputs[a].gradient = a < gain.inputs.size() && gain.inputs[a].size() == inputs[a].gradient.size()
                                     ? gain.inputs[a]
                                     : Eigen::VectorXd::Zero(inputs[a].gradient.size());
        EliminateNuisance(inputs, h, g);
        const Eigen::VectorXd v = h.completeOrthogonalDecomposition().solve(g);
        if (!v.allFinite()) continue;
        calibration.noalias() += gain_sd * gain_sd * v * v.transpose();
        summary.calibration[channel] = gain_sd;
      }
      covariance += calibration;
      summary.calibration_sd.assign(np, NAN);
      for (int a = 0; a < l; ++a) summary.calibration_sd[est[a]] = std::sqrt(std::max(calibration(a, a), 0.0)) * scale[est[a]];
    }
    summary.contributions = Contributions(problem.experiment_labels(), eq, priors, est, scale, np);
    if ((options_.input_noise && eq.input_noise.size() > 0) || !eq.inputs.empty()) {
      summary.input_noise_sd_factor.assign(np, NAN);
      for (int a = 0; a < l; ++a) summary.input_noise_sd_factor[est[a]] = posterior.input_noise_factor[a];
    }
    summary.correlation.resize(l, l);
    for (int a = 0; a < l; ++a) {
      summary.sd[est[a]] = std::sqrt(std::max(covariance(a, a), 0.0)) * scale[est[a]];
      for (int b = 0; b < l; ++b)
        summary.correlation(a, b) = covariance(a, b) / std::sqrt(std::max(covariance(a, a) * covariance(b, b), 1e-300));
    }
    // Estimated parameters the data add nothing to: their interval is their prior's.
    for (int a = 0; a < l; ++a) {
      const auto& prior = choices[est[a]].prior_sd;
      if (prior && summary.sd[est[a]] > 0.9 * *prior)
        summary.warnings.push_back(fmt::format(
            "{} {}: the data barely determine it; its interval is essentially its prior's (sd {:.3g} {}), and the "
            "parameters correlated with it are uncertain accordingly",
            initial.spec(est[a]).key(), initial.spec(est[a]).name, *prior, initial.spec(est[a]).unit));
    }
    // Parameters the data cannot determine: a near-null direction of the information matrix.
    for (const std::vector<int>& direction : posterior.undetermined) {
      std::string names;
      for (int a : direction) names += " " + initial.spec(est[a]).key();
      summary.warnings.push_back(fmt::format(
          "the data cannot determine{} (near-singular information matrix); fix one of them or add experiments", names));
    }
    // Strongly correlated parameters, one warning per group (connected through |r| > 0.99): the
    // stroke zero's direction alone links four parameters, which pair by pair read as six warnings.
    std::vector<int> group(l);
    for (int a = 0; a < l; ++a) group[a] = a;
    const auto root = [&](int a) {
      while (group[a] != a) a = group[a];
      return a;
    };
    for (int a = 0; a < l; ++a)
      for (int b = a + 1; b < l; ++b)
        if (std::abs(summary.correlation(a, b)) > 0.99) group[root(b)] = root(a);
    for (int g = 0; g < l; ++g) {
      std::vector<int> members;
      for (int a = 0; a < l; ++a)
        if (root(a) == g) members.push_back(a);
      if (members.size() < 2) continue;
      std::string names;
      double lo = 1.0, hi = 0.0;
      for (std::size_t i = 0; i < members.size(); ++i) {
        names += (i == 0 ? "" : i + 1 == members.size() ? " and " : ", ") + initial.spec(est[members[i]]).key();
        for (std::size_t j = i + 1; j < members.size(); ++j) {
          const double r = std::abs(summary.correlation(members[i], members[j]));
          if (r > 0.99) lo = std::min(lo, r);
          hi = std::max(hi, r);
        }
      }
      summary.warnings.push_back(
          members.size() == 2
              ? fmt::format("{} are correlated {:.3f}: the data barely tell them apart", names,
                            summary.correlation(members[0], members[1]))
              : fmt::format("{} are correlated (|r| {:.3f} to {:.3f} between pairs): the data barely tell them "
                            "apart",
                            names, lo, hi));
    }
  }

  // Statistics per channel and per experiment.
  summary.observations = std::accumulate(current.counts.begin(), current.counts.end(), 0L);
  summary.loglik = current.LogLikelihood();
  summary.aic = -2.0 * summary.loglik + 2.0 * l;
  summary.bic = -2.0 * summary.loglik + l * std::log(static_cast<double>(std::max(1L, summary.observations)));
  problem.Summarise(current, variance, ratios, summary);
  // A fit that only matches the data with an impossible state (negative absolute pressure, a gas
  // volume through zero) says so: the parameters then mean nothing physical.
  for (const ExperimentFit& e : summary.experiments)
    if (e.converged)
      if (const auto violation = PhysicalViolation(model_, e.solution, theta))
        summary.warnings.push_back(fmt::format("experiment '{}': the fitted state is physically impossible: {}", e.label,
                                               *violation));
  if (!summary.converged && summary.warnings.empty())
    summary.warnings.push_back(fmt::format("estimator: not converged after {} iterations", iteration));
  return summary;
}

bool FitSummary::IsSolutionUsable() const {
  return std::any_of(experiments.begin(), experiments.end(), [](const ExperimentFit& e) { return e.converged; }) &&
         std::isfinite(loglik);
}

const char* ToString(FitVerdict verdict) {
  switch (verdict) {
    case FitVerdict::kAtNoiseFloor: return "at-noise-floor";
    case FitVerdict::kAboveNoiseFloor: return "above-noise-floor";
    case FitVerdict::kNotConverged: return "not-converged";
  }
  return "?";
}

FitVerdict FitSummary::Verdict() const {
  if (!converged || !IsSolutionUsable()) return FitVerdict::kNotConverged;
  // A channel whose noise is unknown (one recorded period) cannot say it is above the floor.
  for (const FitChannel& c : channels)
    if (c.noise_ratio >= kNoiseFloorRatio) return FitVerdict::kAboveNoiseFloor;
  return FitVerdict::kAtNoiseFloor;
}

std::string FitSummary::VerdictText() const {
  std::string ratios;
  for (const FitChannel& c : channels) ratios += fmt::format("{}{} {:.2f}", ratios.empty() ? "" : ", ", c.name, c.noise_ratio);
  switch (Verdict()) {
    case FitVerdict::kAtNoiseFloor:
      if (std::none_of(channels.begin(), channels.end(), [](const FitChannel& c) { return std::isfinite(c.noise_ratio); }))
        return fmt::format("Converged. The noise floor is unknown (fewer than 2 recorded periods), so whether the "
                           "model {} explains all the data can show cannot be judged.",
                           model);
      return fmt::format("Converged at the noise floor (residual over noise variance: {}): the model {} explains all "
                         "the data can show.",
                         ratios, model);
    case FitVerdict::kAboveNoiseFloor: {
      // Where: the experiments and channels furthest above their noise, worst first.
      std::vector<std::pair<double, std::string>> worst;
      for (const ExperimentFit& e : experiments)
        for (const ChannelStatistics& c : e.channels)
          if (c.fitted && c.noise_ratio >= 2.0 * kNoiseFloorRatio)
            worst.emplace_back(c.noise_ratio, fmt::format("{} {} {:.3g}", e.label, c.channel, c.noise_ratio));
      std::sort(worst.rbegin(), worst.rend());
      std::string where;
      for (std::size_t k = 0; k < std::min<std::size_t>(worst.size(), 6); ++k)
        where += (k ? ", " : "") + worst[k].second;
      return fmt::format(
          "Converged, but ABOVE THE NOISE FLOOR: the model {} does not explain the data (residual over noise "
          "variance: {}; threshold {}){}. The intervals are widened for the misfit, but estimates of a model that "
          "lacks physics are biased: run `strut discover` to name what is missing.",
          model, ratios, kNoiseFloorRatio, where.empty() ? "" : "; worst experiments: " + where);
    }
    case FitVerdict::kNotConverged: {
      std::string why = warnings.empty() ? std::string("no reason recorded") : warnings.front();
      return fmt::format("NOT CONVERGED after {} iterations ({}). The values are not an estimate. Try starting values "
                         "closer to the unit (--params or --set), fewer estimated parameters (--estimate paper), or "
                         "--exclude for an experiment without a periodic solution.",
                         iterations, why);
    }
  }
  return {};
}

std::string GainSdText(const std::map<std::string, double>& gain_sd) {
  std::string text;
  for (const auto& [channel, sd] : gain_sd) text += fmt::format("{}{} {:.3g} %", text.empty() ? "" : ", ", channel, 100 * sd);
  return text;
}

std::string FitSummary::BriefReport() const {
  return fmt::format("{}: {} after {} iterations, loglik {:.6g}, BIC {:.6g}, {} warnings", model,
                     converged ? "converged" : "NOT converged", iterations, loglik, bic, warnings.size());
}

double FitSummary::NoiseSd(int i) const {
  const double c = i < static_cast<int>(calibration_sd.size()) && std::isfinite(calibration_sd[i]) ? calibration_sd[i] : 0.0;
  return std::sqrt(std::max(sd[i] * sd[i] - c * c, 0.0));
}

std::string FitSummary::FullReport() const {
  std::string out = BriefReport() + "\n" + VerdictText() + "\n\nparameters:\n";
  for (int i = 0; i < parameters.size(); ++i) {
    const auto& spec = parameters.spec(i);
    const double calibration_part = i < static_cast<int>(calibration_sd.size()) ? calibration_sd[i] : NAN;
    out += fmt::format("  {:<8} {:<28} {:>14.7g} {:<10} {}\n", spec.key(), spec.name, parameters.value(i), spec.unit,
                       !estimated[i]                       ? std::string("(fixed)")
                       : calibration_part > 0.3 * sd[i] ? fmt::format("+- {:.3g} (estimated; calibration {:.3g})", sd[i], calibration_part)
                                                           : fmt::format("+- {:.3g} (estimated)", sd[i]));
  }
  if (!calibration.empty())
    out += fmt::format("  (each sd holds the transducers' calibration, gain sd {}; shown where it is a large part)\n",
                       GainSdText(calibration));
  out += "\nchannels:\n";
  for (const auto& c : channels)
    out += fmt::format("  {:<12} rms {:.4g}  variance {:.4g}  noise floor {:.4g}  noise ratio {:.3g}\n", c.name, c.rms,
                       c.variance, c.noise_floor_variance, c.noise_ratio);
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
  for (const auto& t : transient_experiments) {
    out += fmt::format("  {:<6} {:<7} {:.0f} kg at {:.3g} m/s", t.label, t.kind, t.drop_mass, t.impact_velocity);
    if (!t.converged) {
      out += "  no prediction: " + t.error + "\n";
      continue;
    }
    for (const auto& c : t.channels)
      out += fmt::format("  {}: {:+.3g} / {:.3g} / {:.3g}", c.channel, c.mean, 2 * c.sd, c.noise_ratio);
    out += "\n";
  }
  // What each drop adds: the parameters it sharpens most (sd without it over the sd with it).
  for (const auto& c : contributions) {
    if (c.kind == "periodic") continue;
    std::vector<std::pair<double, int>> gains;
    for (int i = 0; i < parameters.size(); ++i)
      if (estimated[i] && NoiseSd(i) > 0 && c.sd_without[i] > 1.05 * NoiseSd(i))
        gains.emplace_back(c.sd_without[i] / NoiseSd(i), i);
    std::sort(gains.rbegin(), gains.rend());
    std::string list;
    for (std::size_t k = 0; k < std::min<std::size_t>(gains.size(), 6); ++k)
      list += (k ? "; " : "") +
              (std::isinf(gains[k].first)
                   ? fmt::format("{} undetermined without it, sd {:.3g} with", parameters.spec(gains[k].second).key(),
                                 NoiseSd(gains[k].second))
                   : fmt::format("{} sd {:.3g} without it, {:.3g} with ({:.2g} times sharper)",
                                 parameters.spec(gains[k].second).key(), c.sd_without[gains[k].second],
                                 NoiseSd(gains[k].second), gains[k].first));
    out += fmt::format("{} '{}' adds: {}\n", c.kind, c.label,
                       list.empty() ? "no parameter sharper by more than 5 %" : list);
  }
  for (const auto& w : warnings) out += "warning: " + w + "\n";
  return out;
}

}  // namespace strut::ident
