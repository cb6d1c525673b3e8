#include "strut/ident/estimator.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <fmt/format.h>
#include <numeric>
#include <spdlog/spdlog.h>

#include "fit_stages.h"

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
  for (int i = 0; i < np; ++i) {
    if (!choices[i].estimate) continue;
    if (initial.spec(i).experiment_condition)
      throw std::invalid_argument(fmt::format("estimator: {} ({}) is set per experiment from its recording and cannot "
                                              "be estimated",
                                              initial.spec(i).key(), initial.spec(i).name));
    est.push_back(i);
  }
  const int l = static_cast<int>(est.size());

  FitSummary summary;
  summary.model = model_.composition();
  summary.parameters = initial;
  summary.estimates.assign(np, ParameterEstimate{});
  for (int i : est) summary.estimates[i] = {.estimated = true, .prior_sd = choices[i].prior_sd};
  summary.estimated_positions = est;

  // The iterates stay inside the parameters' physical ranges: the line search's trials are projected.
  const internal::ScaledParameters scaled(initial, est);
  const ScaledPriors priors = scaled.Priors(initial, choices);
  const ScaledBounds bounds = scaled.Bounds(initial);
  FitProblem problem(model_, options_, data, issues, est, scaled.scale, transients);
  summary.warnings = problem.warnings();
  problem.Solve(initial.values(), true, 0, progress);
  if (problem.active_count() == 0)
    throw EstimationError("estimator: no experiment has a solution at the starting values");

  internal::MinimizerSummary minimum =
      internal::Minimize(problem, scaled, priors, bounds, options_, initial.values(), progress);
  if (!minimum.message.empty()) summary.warnings.push_back(minimum.message);
  summary.converged = minimum.converged();
  summary.iterations = minimum.iterations;
  summary.parameters.values() = minimum.theta;
  summary.history = minimum.history;

  const std::vector<double> variance = minimum.residuals.Variances(l);
  const FitProblem::NoiseRatios noise = problem.NoiseRatioStatistics();
  bool misfit = false;  // the widening for misfit follows the same test as the verdict
  for (std::size_t b = 0; b < noise.ratio.size(); ++b)
    misfit = misfit || noise.ratio[b] >= NoiseFloorLimit(noise.sd[b], noise.ratio.size());
  internal::CovarianceSummary covariance =
      internal::EstimateCovariance(problem, scaled, priors, options_, minimum, variance, noise.ratio, misfit);
  summary.warnings.insert(summary.warnings.end(), covariance.warnings.begin(), covariance.warnings.end());
  for (std::string& w : internal::CovarianceDiagnostics(covariance, initial, choices, est))
    summary.warnings.push_back(std::move(w));
  for (int i = 0; i < np; ++i) {
    ParameterEstimate& p = summary.estimates[i];
    p.sd = covariance.sd[i];
    if (!covariance.input_noise_sd_factor.empty()) p.input_noise_sd_factor = covariance.input_noise_sd_factor[i];
    if (!covariance.misfit_sd_factor.empty()) p.misfit_sd_factor = covariance.misfit_sd_factor[i];
    if (!covariance.calibration_sd.empty()) p.calibration_sd = covariance.calibration_sd[i];
  }
  summary.calibration = std::move(covariance.calibration);
  summary.correlation = std::move(covariance.correlation);
  summary.contributions = std::move(covariance.contributions);

  // Statistics per channel and per experiment.
  const ResidualSums& current = minimum.residuals;
  summary.observations = std::accumulate(current.counts.begin(), current.counts.end(), 0L);
  summary.loglik = current.LogLikelihood();
  summary.aic = -2.0 * summary.loglik + 2.0 * l;
  summary.bic = -2.0 * summary.loglik + l * std::log(static_cast<double>(std::max(1L, summary.observations)));
  problem.Summarise(current, variance, noise, summary);
  // A fit that only matches the data with an impossible state (negative absolute pressure, a gas
  // volume through zero) says so: the parameters then mean nothing physical.
  for (const ExperimentFit& e : summary.experiments)
    if (e.converged)
      if (const auto violation = PhysicalViolation(model_, e.solution, minimum.theta))
        summary.warnings.push_back(fmt::format("experiment '{}': the fitted state is physically impossible: {}", e.label,
                                               *violation));
  if (!summary.converged && summary.warnings.empty())
    summary.warnings.push_back(fmt::format("estimator: not converged after {} iterations", minimum.iterations));
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

double UpperNormalQuantile(double p) {
  if (!(p > 0.0 && p < 1.0)) throw std::invalid_argument(fmt::format("UpperNormalQuantile: p = {} is not in (0, 1)", p));
  // Bisection on the tail 0.5 erfc(z / sqrt 2), which falls monotonically: 200 halvings of
  // [-40, 40] reach the double's resolution.
  double low = -40.0, high = 40.0;
  for (int k = 0; k < 200 && high - low > 1e-15 * std::max(1.0, std::abs(low)); ++k) {
    const double mid = 0.5 * (low + high);
    (0.5 * std::erfc(mid / std::numbers::sqrt2) > p ? low : high) = mid;
  }
  return 0.5 * (low + high);
}

double NoiseFloorLimit(double sd, std::size_t channels) {
  if (!std::isfinite(sd)) return kNoiseFloorRatio;
  return 1.0 + UpperNormalQuantile(kNoiseFloorFalseAlarm / static_cast<double>(std::max<std::size_t>(1, channels))) * sd;
}

bool FitChannel::AboveNoiseFloor() const {
  return noise_ratio >= (std::isfinite(noise_floor_limit) ? noise_floor_limit : kNoiseFloorRatio);
}

FitVerdict FitSummary::Verdict() const {
  if (!converged || !IsSolutionUsable()) return FitVerdict::kNotConverged;
  // A channel whose noise is unknown (one recorded period) cannot say it is above the floor.
  for (const FitChannel& c : channels)
    if (c.AboveNoiseFloor()) return FitVerdict::kAboveNoiseFloor;
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
          if (c.fitted && c.noise_ratio >= 2.0)
            worst.emplace_back(c.noise_ratio, fmt::format("{} {} {:.3g}", e.label, c.channel, c.noise_ratio));
      std::sort(worst.rbegin(), worst.rend());
      std::string where, limits;
      for (std::size_t k = 0; k < std::min<std::size_t>(worst.size(), 6); ++k)
        where += (k ? ", " : "") + worst[k].second;
      for (const FitChannel& c : channels)
        limits += fmt::format("{}{} {:.3g}", limits.empty() ? "" : ", ", c.name, c.noise_floor_limit);
      return fmt::format(
          "Converged, but ABOVE THE NOISE FLOOR: the model {} does not explain the data (residual over noise "
          "variance: {}; what noise alone exceeds with probability {}: {}){}. The intervals are widened for the "
          "misfit, but estimates of a model that lacks physics are biased: run `strut discover` to name what is "
          "missing.",
          model, ratios, kNoiseFloorFalseAlarm, limits, where.empty() ? "" : "; worst experiments: " + where);
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
  const ParameterEstimate& p = estimates[i];
  const double c = std::isfinite(p.calibration_sd) ? p.calibration_sd : 0.0;
  return std::sqrt(std::max(p.sd * p.sd - c * c, 0.0));
}

bool FitSummary::WidenedForMisfit() const {
  return std::any_of(estimates.begin(), estimates.end(),
                     [](const ParameterEstimate& p) { return std::isfinite(p.misfit_sd_factor); });
}

std::string FitSummary::FullReport() const {
  std::string out = BriefReport() + "\n" + VerdictText() + "\n\nparameters:\n";
  for (int i = 0; i < parameters.size(); ++i) {
    const auto& spec = parameters.spec(i);
    const ParameterEstimate& p = estimates[i];
    out += fmt::format("  {:<8} {:<28} {:>14.7g} {:<10} {}\n", spec.key(), spec.name, parameters.value(i), spec.unit,
                       !p.estimated ? std::string("(fixed)")
                       : p.calibration_sd > 0.3 * p.sd
                           ? fmt::format("+- {:.3g} (estimated; calibration {:.3g})", p.sd, p.calibration_sd)
                           : fmt::format("+- {:.3g} (estimated)", p.sd));
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
      if (estimates[i].estimated && NoiseSd(i) > 0 && c.sd_without[i] > 1.05 * NoiseSd(i))
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
