#include "strut/ident/decisive_test.h"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <numbers>
#include <spdlog/spdlog.h>
#include <stdexcept>

#include "strut/ident/parallel.h"
#include "strut/ident/periodic.h"

namespace strut::ident {
namespace {

double Median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const std::size_t m = v.size() / 2;
  return v.size() % 2 ? v[m] : 0.5 * (v[m - 1] + v[m]);
}

std::vector<double> Spread(double lo, double hi, int count) {
  std::vector<double> out;
  for (int k = 0; k < count; ++k) out.push_back(count == 1 ? 0.5 * (lo + hi) : lo + (hi - lo) * k / (count - 1));
  return out;
}

// A fitted model's periodic response to one sinusoidal stroke, at the end of its session, and the
// directions its parameters' posterior moves it in: J L per channel (n x k), with J the outputs'
// sensitivities to the estimated parameters and L L^T their posterior covariance.
struct Response {
  std::map<std::string, Eigen::VectorXd> outputs;
  std::map<std::string, Eigen::MatrixXd> spread;
};

// Grid points per period of the prediction: enough for the orifice and friction shapes of a sine
// (rig::FitPredictor's 256 predicts the matrix check's peaks; the difference of two models needs the
// same resolution, not more).
constexpr int kPredictionPoints = 256;

class Predictor {
 public:
  explicit Predictor(const FitSummary& fit)
      : model_(Model::Build(fit.model, Causality::kStrokeInput)),
        theta_(fit.parameters.values()),
        solver_(model_, PeriodicSolverOptions{}) {
    // The posterior covariance of the estimated parameters, sd_i r_ij sd_j, as L L^T.
    const std::vector<int>& p = fit.estimated_positions;
    const Eigen::Index k = static_cast<Eigen::Index>(p.size());
    if (k == 0 || fit.correlation.rows() != k || fit.correlation.cols() != k) return;
    Eigen::VectorXd sd(k);
    for (Eigen::Index i = 0; i < k; ++i) sd[i] = fit.estimates[p[i]].sd;
    if (!sd.allFinite()) return;
    const Eigen::MatrixXd covariance = sd.asDiagonal() * fit.correlation * sd.asDiagonal();
    // A square root that survives a covariance singular to rounding: V sqrt(max(lambda, 0)).
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(covariance);
    root_ = eigen.eigenvectors() * eigen.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal();
    positions_ = p;
  }

  std::optional<Response> Predict(double static_position, double amplitude, double frequency) {
    try {
      // Run after the recorded experiments: at the end of the session.
      const std::vector<double> at = model_.AtExperiment(theta_, {1.0, static_position});
      const PeriodicSolution s =
          solver_.Solve(PeriodicInput::Sine(frequency, static_position, amplitude, kPredictionPoints), at);
      Response r;
      std::vector<Eigen::MatrixXd> sensitivities;
      if (!positions_.empty()) sensitivities = solver_.OutputSensitivities(s, at, positions_);
      for (std::size_t c = 0; c < s.channels.size(); ++c) {
        if (s.channels[c] == model_.input_channel()) continue;
        r.outputs[s.channels[c]] = s.outputs.row(c).transpose();
        if (!sensitivities.empty()) r.spread[s.channels[c]] = sensitivities[c] * root_;
      }
      return r;
    } catch (const PeriodicSolverError& e) {
      spdlog::debug("decisive test: {} has no periodic state at {:.1f} mm static, {:.1f} mm, {:g} Hz: {}",
                    model_.composition(), static_position * 1e3, amplitude * 1e3, frequency, e.what());
      return std::nullopt;
    }
  }

 private:
  Model model_;
  std::vector<double> theta_;
  PeriodicSolver solver_;
  std::vector<int> positions_;  // the estimated parameters (empty: the fit has no posterior)
  Eigen::MatrixXd root_;
};

// The linearised discrimination of two models by one test (Buzzi-Ferraris and Forzatti's criterion):
// the expected chi-square between their predictions once both are refitted with the test's data,
// T(P) = Delta^T (W(P)^-1 + V_a + V_b)^-1 Delta, where Delta is the predictions' difference, W(P) the
// inverse noise variance of P periods averaged, and V = J Sigma J^T what each model's parameter
// posterior lets it move. The pieces at one period: a1 = D^T W1 D, b1 = U^T W1 D, H1 = U^T W1 U with
// U = [J_a L_a, J_b L_b]; then T(P) = P a1 - P^2 b1^T (I + P H1)^-1 b1 (Woodbury).
struct Discrimination {
  double a1 = 0.0;
  Eigen::VectorXd b1;
  Eigen::MatrixXd h1;
  double At(long periods) const {
    const double p = static_cast<double>(periods);
    if (b1.size() == 0) return p * a1;
    const Eigen::MatrixXd g = Eigen::MatrixXd::Identity(h1.rows(), h1.cols()) + p * h1;
    return std::max(0.0, p * a1 - p * p * b1.dot(g.ldlt().solve(b1)));
  }
};

}  // namespace

bool TestSpace::IsValid(std::string* error) const {
  const auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (!(stroke_max > stroke_min)) return fail("the stroke range is empty");
  if (!(max_rate > 0) || !(max_force > 0) || !(max_pressure > 0)) return fail("the rate, force and pressure limits must be positive");
  if (frequencies.empty() || static_positions.empty() || amplitudes.empty())
    return fail("no frequency, static position or amplitude to choose from");
  if (!(sample_rate > 0) || periods < 1 || max_periods < periods)
    return fail("the sample rate must be positive, the periods at least 1 and at most max_periods");
  if (!(separation_wanted >= 0)) return fail("separation_wanted must not be negative");
  if (!(overhead_cycles >= 0) || !(static_rate > 0)) return fail("the overhead cycles and the static rate must be positive");
  for (const auto& [channel, sd] : noise_sd)
    if (!(sd > 0)) return fail(fmt::format("the noise sd of {} must be positive", channel));
  if (noise_sd.empty()) return fail("no channel's noise sd is known (every experiment has one period)");
  return true;
}

TestSpace TestSpaceOf(const std::vector<ExperimentData>& experiments) {
  if (experiments.empty()) throw std::invalid_argument("decisive test: no recorded periodic experiment");
  TestSpace space;
  space.stroke_min = INFINITY;
  space.stroke_max = -INFINITY;
  std::vector<double> rates, amplitudes;
  std::map<std::string, std::vector<double>> sds;
  for (const ExperimentData& e : experiments) {
    space.stroke_min = std::min(space.stroke_min, e.static_position - e.amplitude);
    space.stroke_max = std::max(space.stroke_max, e.static_position + e.amplitude);
    space.max_rate = std::max(space.max_rate, 2.0 * std::numbers::pi * e.frequency * e.amplitude);
    amplitudes.push_back(e.amplitude);
    if (std::find(space.frequencies.begin(), space.frequencies.end(), e.frequency) == space.frequencies.end())
      space.frequencies.push_back(e.frequency);
    if (e.sample_rate > 0) rates.push_back(e.sample_rate);
    for (const auto& [name, channel] : e.channels) {
      if (name == "force") space.max_force = std::max(space.max_force, channel.mean.cwiseAbs().maxCoeff());
      if (name == "pressure") space.max_pressure = std::max(space.max_pressure, channel.mean.maxCoeff());
      if (channel.noise_variance > 0) sds[name].push_back(std::sqrt(channel.noise_variance));
    }
  }
  std::sort(space.frequencies.begin(), space.frequencies.end());
  const auto [a_min, a_max] = std::minmax_element(amplitudes.begin(), amplitudes.end());
  space.amplitudes = Spread(*a_min, *a_max, 5);
  space.static_positions = Spread(space.stroke_min + *a_min, space.stroke_max - *a_min, 7);
  space.sample_rate = Median(rates);
  for (const auto& [name, v] : sds) space.noise_sd[name] = Median(v);
  return space;
}

std::string DecisiveTest::Describe() const {
  std::string differences;
  for (const auto& [c, rms] : rms_difference)
    differences += fmt::format("{}{} {:.2f}", differences.empty() ? "" : ", ", c, rms);
  return fmt::format(
      "a sine of {:.1f} mm amplitude at {:.1f} mm static position and {:g} Hz, {} periods recorded ({:.1f} min of rig "
      "time): {} and {} predict outputs that differ by an RMS of {} noise sd (mostly {}), an expected chi-square of "
      "{:.0f} between them once both are refitted with it ({:.0f} a minute; {:.0f} at their fitted values)",
      amplitude * 1e3, static_position * 1e3, frequency, periods, minutes, model_a, model_b, differences, channel,
      separation, separation_per_minute, separation_fixed);
}

std::optional<DecisiveTest> ProposeDecisiveTest(const FitSummary& a, const FitSummary& b, const TestSpace& space) {
  std::string error;
  if (!space.IsValid(&error)) throw std::invalid_argument("decisive test: " + error);
  Predictor predict_a(a), predict_b(b);
  const double middle = space.static_positions[space.static_positions.size() / 2];
  std::optional<DecisiveTest> best;
  Discrimination best_discrimination;
  int candidates = 0;
  for (const double f : space.frequencies)
    for (const double s : space.static_positions)
      for (const double amp : space.amplitudes) {
        if (s - amp < space.stroke_min - 1e-12 || s + amp > space.stroke_max + 1e-12) continue;
        if (2.0 * std::numbers::pi * f * amp > space.max_rate * (1 + 1e-12)) continue;
        ++candidates;
        const std::optional<Response> ra = predict_a.Predict(s, amp, f), rb = predict_b.Predict(s, amp, f);
        if (!ra || !rb) continue;
        DecisiveTest t;
        t.model_a = a.model;
        t.model_b = b.model;
        t.static_position = s;
        t.amplitude = amp;
        t.frequency = f;
        t.periods = space.periods;
        t.sample_rate = space.sample_rate;
        bool within = true;
        double top = 0.0;
        const Eigen::Index k_a = ra->spread.empty() ? 0 : ra->spread.begin()->second.cols();
        const Eigen::Index k_b = rb->spread.empty() ? 0 : rb->spread.begin()->second.cols();
        Discrimination d;
        if (k_a + k_b > 0) {
          d.b1 = Eigen::VectorXd::Zero(k_a + k_b);
          d.h1 = Eigen::MatrixXd::Zero(k_a + k_b, k_a + k_b);
        }
        for (const auto& [channel, ya] : ra->outputs) {
          const auto yb = rb->outputs.find(channel);
          const auto sd = space.noise_sd.find(channel);
          if (yb == rb->outputs.end()) continue;
          const double peak = std::max(ya.cwiseAbs().maxCoeff(), yb->second.cwiseAbs().maxCoeff());
          t.peak[channel] = peak;
          if ((channel == "force" && peak > space.max_force) || (channel == "pressure" && peak > space.max_pressure))
            within = false;
          if (sd == space.noise_sd.end()) continue;
          const Eigen::VectorXd delta = ya - yb->second;
          const double n = static_cast<double>(delta.size());
          t.rms_difference[channel] = std::sqrt(delta.squaredNorm() / n) / sd->second;
          // One period's weight per grid point: the samples a period it stands for over their variance.
          const double w1 = space.sample_rate / f / n / (sd->second * sd->second);
          const double chi2 = w1 * delta.squaredNorm() * static_cast<double>(space.periods);
          t.separation_fixed += chi2;
          d.a1 += w1 * delta.squaredNorm();
          if (chi2 > top) top = chi2, t.channel = channel;
          if (k_a + k_b == 0) continue;
          Eigen::MatrixXd u(delta.size(), k_a + k_b);
          u.leftCols(k_a) = k_a ? ra->spread.at(channel) : Eigen::MatrixXd(delta.size(), 0);
          u.rightCols(k_b) = k_b ? rb->spread.at(channel) : Eigen::MatrixXd(delta.size(), 0);
          d.b1 += w1 * u.transpose() * delta;
          d.h1 += w1 * u.transpose() * u;
        }
        if (!within) continue;
        t.separation = d.At(space.periods);
        t.minutes = (std::abs(s - middle) / space.static_rate + (space.overhead_cycles + space.periods) / f) / 60.0;
        t.separation_per_minute = t.separation / t.minutes;
        if (!best || t.separation_per_minute > best->separation_per_minute) best = t, best_discrimination = d;
      }
  if (!best) return best;
  best->candidates = candidates;
  // More periods where the best test's separation at space.periods falls short of what decides
  // (with the models refitted it grows ever more slowly: the parameters' posterior bounds it).
  long periods = best->periods;
  while (periods < space.max_periods && best_discrimination.At(periods) < space.separation_wanted) ++periods;
  if (periods > best->periods) {
    const double scale = static_cast<double>(periods) / static_cast<double>(best->periods);
    best->minutes += static_cast<double>(periods - best->periods) / best->frequency / 60.0;
    best->separation_fixed *= scale;
    best->separation = best_discrimination.At(periods);
    best->separation_per_minute = best->separation / best->minutes;
    best->periods = periods;
  }
  return best;
}

Decision Decide(const FitData& data, const std::vector<std::string>& models, const SessionFitOptions& options,
                double margin, int threads, const std::vector<const FitSummary*>& starts) {
  if (models.size() < 2) throw std::invalid_argument("decide: at least two models to decide between");
  if (!starts.empty() && starts.size() != models.size())
    throw std::invalid_argument("decide: a starting fit for each model, or none");
  std::vector<FitSummary> fits(models.size());
  ParallelFor(static_cast<int>(models.size()), threads, [&](int k) {
    SessionFitOptions own = options;
    own.composition = models[k];
    own.estimator.threads = 1;
    const Model model = Model::Build(models[k], options.causality);
    // From the model's own fit of the sessions before the test, when there is one: the test's
    // strokes may be where the data's own start has no periodic solution.
    if (!starts.empty() && starts[k]) {
      const TermStart start = StartFromFit(model, *starts[k]);
      try {
        fits[k] = Estimator(model, own.estimator).Fit(data.experiments, start.start, start.choices, data.issues);
      } catch (const EstimationError& e) {
        spdlog::debug("decide: {} from its fit before the test: {}", models[k], e.what());
      } catch (const PeriodicSolverError& e) {
        spdlog::debug("decide: {} from its fit before the test: {}", models[k], e.what());
      }
      if (fits[k].converged && fits[k].IsSolutionUsable()) return;
    }
    FitSummary prepared = FitPrepared(data, model, own).summary;
    if (!(fits[k].converged && fits[k].IsSolutionUsable()) &&
        (prepared.converged || !(fits[k].loglik > prepared.loglik)))
      fits[k] = std::move(prepared);
  });
  return DecideByBic(models, std::move(fits), margin);
}

Decision DecideByBic(const std::vector<std::string>& models, std::vector<FitSummary> fits, double margin) {
  if (models.size() < 2 || fits.size() != models.size())
    throw std::invalid_argument("decide: a fit for each of at least two models");
  Decision d;
  d.models = models;
  d.margin = margin;
  d.fits = std::move(fits);
  std::vector<int> order;
  for (int k = 0; k < static_cast<int>(models.size()); ++k)
    if (d.fits[k].converged && d.fits[k].IsSolutionUsable()) order.push_back(k);
  std::sort(order.begin(), order.end(), [&](int a, int b) { return d.fits[a].bic < d.fits[b].bic; });
  std::string bics;
  for (int k = 0; k < static_cast<int>(models.size()); ++k)
    bics += fmt::format("{}{} {}", bics.empty() ? "" : ", ", models[k],
                        d.fits[k].converged ? fmt::format("BIC {:.1f}", d.fits[k].bic) : "did not converge");
  if (order.empty()) {
    d.conclusion = fmt::format("No model converged on the data with the decisive test ({}): nothing is decided.", bics);
    return d;
  }
  d.delta_bic = order.size() > 1 ? d.fits[order[1]].bic - d.fits[order[0]].bic : INFINITY;
  // A model whose fit stopped short has a BIC above its own optimum's: losing by it rules nothing out.
  std::string unfinished;
  for (int k = 0; k < static_cast<int>(models.size()); ++k)
    if (!(d.fits[k].converged && d.fits[k].IsSolutionUsable())) unfinished += (unfinished.empty() ? "" : ", ") + models[k];
  if (!unfinished.empty()) {
    d.conclusion = fmt::format("With the decisive test {} did not converge, so its best BIC is unknown and nothing is "
                               "decided; {} fits best so far ({}).",
                               unfinished, models[order[0]], bics);
  } else if (d.delta_bic > margin) {
    d.winner = order[0];
    d.conclusion = fmt::format("With the decisive test the data choose {}: every other model's BIC lies {:.1f} or more "
                               "above it, beyond the margin of {:g} ({}).",
                               models[d.winner], d.delta_bic, margin, bics);
  } else {
    d.conclusion = fmt::format("Even with the decisive test the data do not decide: {} and {} lie {:.1f} apart in BIC, "
                               "within the margin of {:g} ({}).",
                               models[order[0]], models[order[1]], d.delta_bic, margin, bics);
  }
  return d;
}

}  // namespace strut::ident
