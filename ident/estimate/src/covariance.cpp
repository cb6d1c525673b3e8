#include <algorithm>
#include <cmath>
#include <fmt/format.h>

#include "fit_stages.h"

namespace strut::ident::internal {
namespace {

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

// Honest intervals above the noise floor: residuals of a model that lacks physics are systematic,
// not white, and the white-noise covariance at the residual variance is then far too narrow. Each
// parameter's sd is widened to what the experiments' disagreement implies (the sandwich over
// experiments) where that is larger; whole rows and columns, keeping the correlations.
void WidenForMisfit(const FitProblem& problem, const std::vector<int>& est, const std::vector<double>& ratio,
                    const NormalEquations& eq, const Posterior& posterior, Eigen::MatrixXd& covariance,
                    CovarianceSummary& out, int np) {
  const int l = static_cast<int>(est.size());
  const Eigen::MatrixXd robust = ExperimentSandwich(posterior.covariance, eq.experiment_gradient);
  out.misfit_sd_factor.assign(np, NAN);
  double widest = 1.0;
  for (int a = 0; a < l; ++a) {
    const double factor = std::sqrt(std::max(1.0, robust(a, a) / std::max(covariance(a, a), 1e-300)));
    out.misfit_sd_factor[est[a]] = factor;
    widest = std::max(widest, factor);
  }
  for (int a = 0; a < l; ++a)
    for (int b = 0; b < l; ++b) covariance(a, b) *= out.misfit_sd_factor[est[a]] * out.misfit_sd_factor[est[b]];
  std::string channels;
  for (std::size_t b = 0; b < ratio.size(); ++b)
    channels += fmt::format("{}{} {:.3g}", channels.empty() ? "" : ", ", problem.channels()[b], ratio[b]);
  out.warnings.push_back(fmt::format(
      "above the noise floor (residual over noise variance: {}): the intervals are widened by up to {:.3g} times "
      "for what the experiments disagree on (sandwich over experiments); a model that lacks physics is biased "
      "beyond any interval",
      channels, widest));
}

// Transducer calibration (EstimatorOptions::gain_sd): a channel reading (1 + g) times the truth
// moves the estimate by g v, v = H^-1 d(J^T W e)/dg (an output's residuals gain g y, the input's
// gain moves every output along the input; the estimated inputs eliminated as in the Bard step); a
// gain known to sd s adds s^2 v v^T to the covariance.
Eigen::MatrixXd CalibrationCovariance(FitProblem& problem, const EstimatorOptions& options, const ScaledPriors& priors,
                                      const NormalEquations& eq, const std::vector<double>& theta,
                                      const std::vector<double>& variance, CovarianceSummary& out) {
  const int l = static_cast<int>(eq.information.rows());
  Eigen::MatrixXd calibration = Eigen::MatrixXd::Zero(l, l);
  Eigen::MatrixXd information = eq.information;  // with the priors, as in the posterior
  information.diagonal() += priors.precision;
  for (const auto& [channel, gain_sd] : options.gain_sd) {
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
    out.calibration[channel] = gain_sd;
  }
  return calibration;
}

}  // namespace

CovarianceSummary EstimateCovariance(FitProblem& problem, const ScaledParameters& parameters,
                                     const ScaledPriors& priors, const EstimatorOptions& options,
                                     const MinimizerSummary& minimum, const std::vector<double>& variance,
                                     const std::vector<double>& ratio, bool misfit) {
  const int np = static_cast<int>(parameters.scale.size());
  const int l = parameters.size();
  const std::vector<int>& est = parameters.estimated;
  const std::vector<double>& scale = parameters.scale;
  CovarianceSummary out;
  out.sd.assign(np, NAN);
  if (l == 0 || !options.uncertainty) return out;
  const NormalEquations eq =
      problem.Linearise(minimum.theta, variance, {true, false, options.input_noise, minimum.estimating_inputs});
  const Posterior posterior = PosteriorCovariance(eq.information, eq.input_noise, priors, eq.inputs);
  out.undetermined = posterior.undetermined;
  Eigen::MatrixXd covariance = posterior.covariance;
  if (misfit) WidenForMisfit(problem, est, ratio, eq, posterior, covariance, out, np);
  if (!options.gain_sd.empty()) {
    const Eigen::MatrixXd calibration = CalibrationCovariance(problem, options, priors, eq, minimum.theta, variance, out);
    covariance += calibration;
    out.calibration_sd.assign(np, NAN);
    for (int a = 0; a < l; ++a) out.calibration_sd[est[a]] = std::sqrt(std::max(calibration(a, a), 0.0)) * scale[est[a]];
  }
  out.contributions = Contributions(problem.experiment_labels(), eq, priors, est, scale, np);
  if ((options.input_noise && eq.input_noise.size() > 0) || !eq.inputs.empty()) {
    out.input_noise_sd_factor.assign(np, NAN);
    for (int a = 0; a < l; ++a) out.input_noise_sd_factor[est[a]] = posterior.input_noise_factor[a];
  }
  out.correlation.resize(l, l);
  for (int a = 0; a < l; ++a) {
    out.sd[est[a]] = std::sqrt(std::max(covariance(a, a), 0.0)) * scale[est[a]];
    for (int b = 0; b < l; ++b)
      out.correlation(a, b) = covariance(a, b) / std::sqrt(std::max(covariance(a, a) * covariance(b, b), 1e-300));
  }
  return out;
}

std::vector<std::string> CovarianceDiagnostics(const CovarianceSummary& covariance, const ParameterSet& initial,
                                               const std::vector<ParameterChoice>& choices,
                                               const std::vector<int>& est) {
  std::vector<std::string> warnings;
  const int l = static_cast<int>(est.size());
  if (covariance.correlation.rows() != l) return warnings;
  // Estimated parameters the data add nothing to: their interval is their prior's.
  for (int a = 0; a < l; ++a) {
    const auto& prior = choices[est[a]].prior_sd;
    if (prior && covariance.sd[est[a]] > 0.9 * *prior)
      warnings.push_back(fmt::format(
          "{} {}: the data barely determine it; its interval is essentially its prior's (sd {:.3g} {}), and the "
          "parameters correlated with it are uncertain accordingly",
          initial.spec(est[a]).key(), initial.spec(est[a]).name, *prior, initial.spec(est[a]).unit));
  }
  // Parameters the data cannot determine: a near-null direction of the information matrix.
  for (const std::vector<int>& direction : covariance.undetermined) {
    std::string names;
    for (int a : direction) names += " " + initial.spec(est[a]).key();
    warnings.push_back(fmt::format(
        "the data cannot determine{} (near-singular information matrix); fix one of them or add experiments", names));
  }
  // Strongly correlated parameters, one warning per group (connected through |r| > 0.99): the
  // stroke zero's direction alone links four parameters, which pair by pair read as six warnings.
  const Eigen::MatrixXd& r = covariance.correlation;
  std::vector<int> group(l);
  for (int a = 0; a < l; ++a) group[a] = a;
  const auto root = [&](int a) {
    while (group[a] != a) a = group[a];
    return a;
  };
  for (int a = 0; a < l; ++a)
    for (int b = a + 1; b < l; ++b)
      if (std::abs(r(a, b)) > 0.99) group[root(b)] = root(a);
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
        const double rij = std::abs(r(members[i], members[j]));
        if (rij > 0.99) lo = std::min(lo, rij);
        hi = std::max(hi, rij);
      }
    }
    warnings.push_back(members.size() == 2
                           ? fmt::format("{} are correlated {:.3f}: the data barely tell them apart", names,
                                         r(members[0], members[1]))
                           : fmt::format("{} are correlated (|r| {:.3f} to {:.3f} between pairs): the data barely "
                                         "tell them apart",
                                         names, lo, hi));
  }
  return warnings;
}

}  // namespace strut::ident::internal
