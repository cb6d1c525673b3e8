#include "strut/ident/discover.h"

#include <algorithm>
#include <chrono>
#include <climits>
#include <cmath>
#include <fmt/format.h>
#include <numeric>
#include <numbers>
#include <optional>
#include <spdlog/spdlog.h>

#include "strut/ident/parallel.h"
#include "strut/ident/initial_values.h"
#include "strut/ident/catalogue.h"

namespace strut::ident {
namespace {

// Residuals of one experiment and channel in units of the noise of the averaged data, with the
// measured stroke, stroke rate and pressure at the same phases.
struct Normalised {
  const ExperimentFit* experiment = nullptr;
  std::string channel;
  Eigen::VectorXd z, stroke, rate, pressure;
};

std::vector<Normalised> Collect(const FitSummary& fit) {
  std::vector<Normalised> out;
  for (const ExperimentFit& e : fit.experiments) {
    if (!e.converged || !e.measured.count("stroke")) continue;
    const PeriodicSeries stroke = PeriodicSeries::Fit(e.measured.at("stroke"), e.frequency);
    for (const auto& [channel, r] : e.residual) {
      const double variance = e.noise_variance.count(channel) ? e.noise_variance.at(channel) : NAN;
      if (!(variance > 0)) continue;
      Normalised n{&e, channel, r / std::sqrt(variance), e.measured.at("stroke"), Eigen::VectorXd(r.size()), {}};
      n.rate = stroke.OnPhases(static_cast<int>(r.size()), 1);
      if (e.measured.count("pressure")) n.pressure = e.measured.at("pressure");
      out.push_back(std::move(n));
    }
  }
  return out;
}

// t-statistic of the least-squares coefficient of `x` in z ~ c + b x (white unit-variance noise).
double TStatistic(const Eigen::VectorXd& z, const Eigen::VectorXd& x) {
  const Eigen::VectorXd centred = x.array() - x.mean();
  const double norm = centred.norm();
  return norm > 0 ? centred.dot(z) / norm : 0.0;
}

std::string Group(const ExperimentFit& e) { return e.group.empty() ? "(none)" : e.group; }

// Wall time of a stage, for the timing lines of the debug log.
struct Stopwatch {
  std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
  double Seconds() const { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); }
};

}  // namespace

bool DiscoverOptions::IsValid(std::string* error) const {
  const auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (!(bic_threshold >= 0)) return fail("bic_threshold must not be negative");
  if (cv_folds < 0 || cv_folds == 1) return fail("cv_folds must be 0 (off) or at least 2");
  if (!(cv_improvement > 0 && cv_improvement <= 1)) return fail("cv_improvement must be in (0, 1]");
  if (!(cv_alpha > 0 && cv_alpha < 1)) return fail("cv_alpha must be in (0, 1)");
  if (!(min_improvement > 0 && min_improvement < 1)) return fail("min_improvement must be in (0, 1)");
  if (max_terms < 0 || threads < 1) return fail("max_terms must not be negative and threads at least 1");
  if (!(screen_margin >= 0)) return fail("screen_margin must not be negative");
  return true;
}

std::map<std::string, double> PooledNoiseRatio(const FitSummary& fit) {
  std::map<std::string, double> ratio;
  for (const FitChannel& c : fit.channels) ratio[c.name] = c.noise_ratio;
  return ratio;
}

namespace {

// Signatures of physics beyond the paper's (damper-physics.md §2): the residual's pooled t
// against a regressor that only that physics produces once the baseline's terms are fitted.
void BeyondThePaperFindings(const std::string& channel, const std::vector<const Normalised*>& items,
                            std::vector<Finding>& findings) {
  const auto pooled = [&](auto&& regressor) {
    double sum = 0.0;
    for (const Normalised* n : items) {
      Eigen::VectorXd x(n->z.size());
      for (Eigen::Index i = 0; i < x.size(); ++i) x[i] = regressor(*n, i);
      sum += TStatistic(n->z, x);
    }
    return sum / std::sqrt(std::max<std::size_t>(1, items.size()));
  };
  // Even in the stroke rate: orifice damping that differs between extension and compression (an
  // odd damping law leaves no residual even in the rate).
  const double even = pooled([](const Normalised& n, Eigen::Index i) { return n.rate[i] * n.rate[i]; });
  findings.push_back({"rate-asymmetry", channel, std::abs(even),
                      fmt::format("{} residual even in the stroke rate (growing with q'^2): pooled t {:+.1f}, more "
                                  "damping in {} than in {}",
                                  channel, even, even < 0 ? "extension" : "compression",
                                  even < 0 ? "compression" : "extension")});
  // Damping that grows with the stroke: the residual on q q'|q'| (the baseline fitted q'|q'|).
  const double deep = pooled([](const Normalised& n, Eigen::Index i) {
    return n.stroke[i] * n.rate[i] * std::abs(n.rate[i]);
  });
  findings.push_back({"position-damping", channel, std::abs(deep),
                      fmt::format("{} residual on stroke times q'|q'|: pooled t {:+.1f}, the damping {} with the "
                                  "stroke",
                                  channel, deep, deep > 0 ? "grows" : "falls")});
  // A friction level that differs with the direction: even in the rate, a step at the reversals
  // (sliding friction saturates within about 1 % of the peak rate).
  const double step = pooled([](const Normalised& n, Eigen::Index i) {
    const double width = 0.01 * std::max(n.rate.cwiseAbs().maxCoeff(), 1e-9);
    const double a = 2.0 / std::numbers::pi * std::atan(n.rate[i] / width);
    return a * a;
  });
  findings.push_back({"friction-direction", channel, std::abs(step),
                      fmt::format("{} residual stepping at the reversals, even in the rate: pooled t {:+.1f}, more "
                                  "friction in {}",
                                  channel, step, step > 0 ? "compression" : "extension")});
  // A thermal loop that grows with the pressure: the residual in phase with the rate, times p.
  if (std::all_of(items.begin(), items.end(), [](const Normalised* n) { return n->pressure.size() == n->z.size(); })) {
    const double loop = pooled([](const Normalised& n, Eigen::Index i) { return n.pressure[i] * 1e-6 * n.rate[i]; });
    findings.push_back({"loop-pressure", channel, std::abs(loop),
                        fmt::format("{} residual in phase with the stroke rate, growing with the pressure: pooled t "
                                    "{:+.1f}",
                                    channel, loop)});
  }
  // A gas law that softens at deep compression: the residual on the stroke cubed (what the
  // polytropic and ideal laws with their fitted constants leave).
  const double cubic = pooled([](const Normalised& n, Eigen::Index i) { return std::pow(n.stroke[i], 3); });
  findings.push_back({"deep-softening", channel, std::abs(cubic),
                      fmt::format("{} residual on the stroke cubed: pooled t {:+.1f}, the gas {} at deep compression",
                                  channel, cubic, cubic < 0 ? "softer" : "stiffer")});
}

}  // namespace

std::vector<Finding> LocateMismatch(const FitSummary& fit) {
  const std::vector<Normalised> all = Collect(fit);
  std::vector<Finding> findings;
  std::map<std::string, std::vector<const Normalised*>> by_channel;
  for (const Normalised& n : all) by_channel[n.channel].push_back(&n);
  for (const auto& [channel, items] : by_channel) {
    // Group bias: the mean residual per static-position group.
    std::map<std::string, std::pair<double, long>> groups;
    double total = 0.0;
    long count = 0;
    for (const Normalised* n : items) {
      groups[Group(*n->experiment)].first += n->z.sum();
      groups[Group(*n->experiment)].second += n->z.size();
      total += n->z.sum();
      count += n->z.size();
    }
    if (groups.size() >= 2) {
      double chi = 0.0;
      std::string detail;
      for (const auto& [g, s] : groups) {
        const double mean = s.first / s.second;
        chi += s.second * std::pow(mean - total / count, 2);
        detail += fmt::format("{}{} {:+.2f}", detail.empty() ? "" : ", ", g, mean);
      }
      findings.push_back({"group-bias", channel, std::sqrt(chi),
                          fmt::format("mean {} residual by static-position group (noise units): {}", channel, detail)});
    }
    // Drift over the session: each experiment's mean residual (its t) against when it was recorded.
    {
      Eigen::VectorXd mean_t(items.size()), when(items.size());
      for (std::size_t k = 0; k < items.size(); ++k) {
        mean_t[k] = items[k]->z.sum() / std::sqrt(static_cast<double>(std::max<Eigen::Index>(1, items[k]->z.size())));
        when[k] = items[k]->experiment->session_time;
      }
      if (items.size() >= 3 && when.maxCoeff() > when.minCoeff()) {
        const double t = TStatistic(mean_t, when);
        findings.push_back({"session-drift", channel, std::abs(t),
                            fmt::format("mean {} residual against recording order: t {:+.1f}, {} over the session",
                                        channel, t, t > 0 ? "the measured level rising" : "the measured level falling")});
      }
    }
    // Loop area against frequency: residual in phase with the stroke rate, slow against fast tests.
    double slow = 0.0, fast = 0.0;
    int n_slow = 0, n_fast = 0;
    double velocity_t = 0.0;
    for (const Normalised* n : items) {
      const double t = TStatistic(n->z, n->rate);
      velocity_t += t;
      if (n->experiment->frequency <= 0.2) slow += t * t, ++n_slow;
      if (n->experiment->frequency >= 1.0) fast += t * t, ++n_fast;
    }
    if (n_slow > 0 && n_fast > 0) {
      const double score = std::sqrt(slow / n_slow) - std::sqrt(fast / n_fast);
      findings.push_back({"loop-frequency", channel, score,
                          fmt::format("{} residual in phase with the stroke rate (a loop): rms t {:.1f} at <= 0.2 Hz "
                                      "against {:.1f} at >= 1 Hz",
                                      channel, std::sqrt(slow / n_slow), std::sqrt(fast / n_fast))});
    }
    findings.push_back({"velocity", channel, std::abs(velocity_t) / std::sqrt(std::max<std::size_t>(1, items.size())),
                        fmt::format("{} residual proportional to the stroke rate: pooled t {:+.1f}", channel,
                                    velocity_t / std::sqrt(std::max<std::size_t>(1, items.size())))});
    // Where in the cycle and in the stroke: near reversals, near full extension.
    const auto localised = [&](const char* locus, auto&& inside, const std::string& where) {
      double in = 0.0, out = 0.0;
      long n_in = 0, n_out = 0;
      for (const Normalised* n : items)
        for (Eigen::Index i = 0; i < n->z.size(); ++i) {
          if (inside(*n, i))
            in += n->z[i] * n->z[i], ++n_in;
          else
            out += n->z[i] * n->z[i], ++n_out;
        }
      if (n_in < 8 || n_out < 8) return;
      const double ms_in = in / n_in, ms_out = out / n_out;
      // Excess mean square inside over outside, in standard errors of a chi-square mean.
      const double score = (ms_in - ms_out) / (std::sqrt(2.0 / n_in) * std::max(ms_out, 1.0));
      findings.push_back({locus, channel, score,
                          fmt::format("{} residual mean square {:.1f} {} against {:.1f} elsewhere (noise units)",
                                      channel, ms_in, where, ms_out)});
    };
    localised("reversal",
              [](const Normalised& n, Eigen::Index i) {
                return std::abs(n.rate[i]) < 0.1 * n.rate.cwiseAbs().maxCoeff();
              },
              "near the velocity reversals");
    localised("extension", [](const Normalised& n, Eigen::Index i) { return n.stroke[i] < 0.015; },
              "within 15 mm of full extension");
    // Stiffness that changes with pressure: the curvature of the residual in the pressure.
    Eigen::VectorXd z_all, p2_all;
    std::vector<double> zs, p2s;
    for (const Normalised* n : items) {
      if (n->pressure.size() != n->z.size()) continue;
      for (Eigen::Index i = 0; i < n->z.size(); ++i) {
        zs.push_back(n->z[i]);
        p2s.push_back(n->pressure[i] * n->pressure[i] * 1e-12);
      }
    }
    if (zs.size() > 16) {
      const double t = TStatistic(Eigen::Map<Eigen::VectorXd>(zs.data(), zs.size()),
                                  Eigen::Map<Eigen::VectorXd>(p2s.data(), p2s.size()));
      findings.push_back({t > 0 ? "pressure-stiffening" : "pressure-softening", channel, std::abs(t),
                          fmt::format("{} residual {} with the square of the pressure: t {:+.1f}", channel,
                                      t > 0 ? "grows" : "falls", t)});
    }
    BeyondThePaperFindings(channel, items, findings);
  }
  std::sort(findings.begin(), findings.end(), [](const Finding& a, const Finding& b) { return a.score > b.score; });
  return findings;
}

namespace {

// The held-out noise ratios of fold k of `folds` (experiments a with a % folds == k), all channels
// pooled per experiment; empty when the refit or a prediction has no solution.
// `iterations`: the refit's.
std::optional<std::vector<double>> HeldOutRatios(const FitData& data, const Model& model, const FitSummary& fit,
                                                 const EstimatorOptions& estimator, int folds, int k, int& iterations) {
  std::vector<ParameterChoice> choices(fit.parameters.size());
  for (int i = 0; i < fit.parameters.size(); ++i) {
    choices[i].estimate = fit.estimates[i].estimated;
    if (fit.estimates[i].estimated && fit.parameters.spec(i).prior_sd > 0) choices[i].prior_sd = fit.parameters.spec(i).prior_sd;
  }
  const std::vector<ParameterChoice> fixed(fit.parameters.size());
  // Only the refit's estimate is used: no posterior at its end.
  EstimatorOptions refit_options = estimator;
  refit_options.uncertainty = false;
  std::vector<ExperimentData> train, held;
  for (int a = 0; a < static_cast<int>(data.experiments.size()); ++a)
    (a % folds == k ? held : train).push_back(data.experiments[a]);
  std::vector<double> ratios;
  try {
    const FitSummary refit = Estimator(model, refit_options).Fit(train, fit.parameters, choices, data.issues);
    iterations = refit.iterations;
    if (!refit.IsSolutionUsable()) return std::nullopt;
    const FitSummary predicted = Estimator(model, refit_options).Fit(held, refit.parameters, fixed, data.issues);
    for (const ExperimentFit& e : predicted.experiments) {
      if (!e.converged) return std::nullopt;
      double sum = 0.0;
      long n = 0;
      for (const auto& [channel, r] : e.residual) {
        const double variance = e.noise_variance.at(channel);
        if (!(variance > 0)) continue;
        sum += r.squaredNorm() / variance;
        n += r.size();
      }
      if (n > 0) ratios.push_back(sum / n);
    }
  } catch (const EstimationError& e) {  // the fold's data have no solution: no ratio from it
    spdlog::debug("cross-validation fold {} of {}: {}", k + 1, model.composition(), e.what());
    return std::nullopt;
  } catch (const PeriodicSolverError& e) {
    spdlog::debug("cross-validation fold {} of {}: {}", k + 1, model.composition(), e.what());
    return std::nullopt;
  }
  return ratios;
}

// The held-out ratios of all folds' experiments (in fold order, the same for every model) and their
// median; empty and NaN when a fold had no solution.
struct HeldOut {
  std::vector<double> ratios;
  double median = NAN;
};
HeldOut PoolHeldOut(const std::vector<std::optional<std::vector<double>>>& folds) {
  HeldOut out;
  for (const auto& fold : folds) {
    if (!fold) return {};
    out.ratios.insert(out.ratios.end(), fold->begin(), fold->end());
  }
  if (out.ratios.empty()) return out;
  // The median over the held-out experiments: an effect that only one experiment shows (an end
  // stop that only the deepest low-position experiment reaches) cannot be learnt without that
  // experiment, and its one wild prediction must not outweigh the others, which it fits well.
  std::vector<double> sorted = out.ratios;
  const auto middle = sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2);
  std::nth_element(sorted.begin(), middle, sorted.end());
  out.median = sorted.size() % 2 == 1 ? *middle : 0.5 * (*middle + *std::max_element(sorted.begin(), middle));
  return out;
}

// Whether the candidate's held-out predictions beat the current model's: by the median (to
// cv_improvement), or experiment by experiment (the signed-rank test at cv_alpha).
bool PredictsHeldOutBetter(const HeldOut& candidate, const HeldOut& current, const DiscoverOptions& options) {
  if (!std::isfinite(candidate.median)) return false;
  if (!std::isfinite(current.median)) return true;
  if (candidate.median <= options.cv_improvement * current.median) return true;
  if (candidate.ratios.size() != current.ratios.size()) return false;
  std::vector<double> log_ratios;
  for (std::size_t e = 0; e < candidate.ratios.size(); ++e)
    log_ratios.push_back(std::log(candidate.ratios[e] / current.ratios[e]));
  return SignedRankPValue(log_ratios) < options.cv_alpha;
}

// A model and its fit whose held-out noise ratio is wanted.
struct CrossValidation {
  const Model* model;
  const FitSummary* fit;
};

// The held-out noise ratios of several models at once: all their folds' refits, `threads` at a time.
std::vector<HeldOut> CrossValidate(const FitData& data, const std::vector<CrossValidation>& models,
                                   const EstimatorOptions& estimator, int folds, int threads) {
  folds = std::min(folds, static_cast<int>(data.experiments.size()));
  if (folds < 2) return std::vector<HeldOut>(models.size());
  // Folds interleave the experiments (a, e, i, m; b, f, j, n; ...), so no fold takes a whole
  // static-position group or frequency away and the refit need not extrapolate.
  std::vector<std::optional<std::vector<double>>> ratios(models.size() * folds);
  std::vector<double> seconds(ratios.size());
  std::vector<int> iterations(ratios.size());
  ParallelFor(static_cast<int>(ratios.size()), threads, [&](int task) {
    const Stopwatch watch;
    const CrossValidation& m = models[task / folds];
    ratios[task] = HeldOutRatios(data, *m.model, *m.fit, estimator, folds, task % folds, iterations[task]);
    seconds[task] = watch.Seconds();
  });
  std::vector<HeldOut> out;
  for (std::size_t m = 0; m < models.size(); ++m) {
    const auto first = ratios.begin() + static_cast<std::ptrdiff_t>(m * folds);
    out.push_back(PoolHeldOut({first, first + folds}));
    std::string fold_times;
    for (int k = 0; k < folds; ++k)
      fold_times += fmt::format(" {:.2f} s ({} iterations)", seconds[m * folds + k], iterations[m * folds + k]);
    spdlog::debug("timing: cross-validation of {}, folds:{}", models[m].model->composition(), fold_times);
    std::string held;
    for (int k = 0; k < folds; ++k)
      if (const auto& fold = ratios[m * folds + k])
        for (double r : *fold) held += fmt::format(" {:.3f}", r);
    spdlog::debug("cross-validation of {}: held-out ratios by fold:{}", models[m].model->composition(), held);
  }
  return out;
}

}  // namespace

double CrossValidatedNoiseRatio(const FitData& data, const Model& model, const FitSummary& fit,
                                const EstimatorOptions& estimator, int folds, int threads) {
  return CrossValidate(data, {{&model, &fit}}, estimator, folds, threads).front().median;
}

double SignedRankPValue(const std::vector<double>& differences) {
  std::vector<double> magnitude;
  std::vector<bool> positive;
  for (double d : differences)
    if (d != 0.0 && std::isfinite(d)) magnitude.push_back(std::abs(d)), positive.push_back(d > 0);
  const int n = static_cast<int>(magnitude.size());
  if (n == 0) return 1.0;
  // Twice the mid-ranks, whole numbers.
  std::vector<int> order(n), rank2(n);
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) { return magnitude[a] < magnitude[b]; });
  for (int i = 0; i < n;) {
    int j = i;
    while (j + 1 < n && magnitude[order[j + 1]] == magnitude[order[i]]) ++j;
    for (int k = i; k <= j; ++k) rank2[order[k]] = i + j + 2;  // 2 x the mean of ranks i+1 .. j+1
    i = j + 1;
  }
  int observed = 0, total = 0;
  for (int i = 0; i < n; ++i) {
    total += rank2[i];
    if (positive[i]) observed += rank2[i];
  }
  // The number of sign patterns for every sum of positive ranks: each rank in or out of the sum.
  std::vector<double> ways(static_cast<std::size_t>(total) + 1, 0.0);
  ways[0] = 1.0;
  for (int i = 0; i < n; ++i)
    for (int sum = total; sum >= rank2[i]; --sum) ways[sum] += ways[sum - rank2[i]];
  double at_most = 0.0;
  for (int sum = 0; sum <= observed; ++sum) at_most += ways[sum];
  return at_most / std::ldexp(1.0, n);
}

namespace {

double WorstRatio(const std::map<std::string, double>& ratio) {
  double worst = 0.0;
  for (const auto& [c, r] : ratio) worst = std::max(worst, std::isfinite(r) ? r : INFINITY);
  return worst;
}

bool AtNoiseFloor(const FitSummary& fit) {
  return std::none_of(fit.channels.begin(), fit.channels.end(), [](const FitChannel& c) { return c.AboveNoiseFloor(); });
}

// Whether some channel's ratio falls from `current` to `candidate` by more than noise moves it: the
// floor test's z times the ratio's sd, which is how far the channel's limit lies above 1.
bool FallsBeyondNoise(const FitSummary& current, const FitSummary& candidate) {
  for (const FitChannel& c : current.channels) {
    const double margin = std::isfinite(c.noise_ratio_sd) ? c.noise_floor_limit - 1.0 : 0.0;
    for (const FitChannel& k : candidate.channels)
      if (k.name == c.name && c.noise_ratio - k.noise_ratio > margin) return true;
  }
  return false;
}

double MeanRatio(const std::map<std::string, double>& ratio) {
  double sum = 0.0;
  for (const auto& [c, r] : ratio) sum += r;
  return ratio.empty() ? 0.0 : sum / ratio.size();
}

const TermEntry& CatalogueEntry(const std::string& term) {
  const auto& catalogue = Catalogue();
  return *std::find_if(catalogue.begin(), catalogue.end(), [&](const TermEntry& e) { return e.name == term; });
}

// One round's candidates: each term that composes with the current model, its refit and its verdict.
struct Round {
  std::vector<std::pair<std::string, std::string>> candidates;  // term, composition
  std::vector<CandidateFit> results;
  std::vector<FitSummary> fits;
  std::vector<HeldOut> held_out;  // per candidate, its held-out ratios where it was cross-validated
};

// One discovery, stage by stage: the baseline, then per round the candidates, their refits, the
// selection (BIC, noise ratio, held-out prediction), and at the end the conclusion.
class DiscoveryRun {
 public:
  DiscoveryRun(const FitData& data, const SessionFitOptions& fit_options, const DiscoverOptions& options,
               const std::function<void(const std::string&)>& progress)
      : data_(data), options_(options), progress_(progress), causality_(fit_options.causality),
        base_(fit_options.composition), session_options_(fit_options) {
    // Every fit also solves its experiments on `threads` threads, beside the candidates and folds run
    // side by side: the baseline, and the last candidate of a round, still use every core. A fit sums
    // its experiments in order, so the answers do not depend on the count.
    session_options_.estimator.threads = options.threads;
  }

  DiscoveryResult Run();

 private:
  void Say(const std::string& text) const {
    spdlog::info("{}", text);
    if (progress_) progress_(text);
  }
  FitSummary FitCandidate(const std::string& term, const Model& model, TermStart start, const FitSummary& previous) const;
  std::optional<std::string> Screened(const TermStart& start, const FitSummary& current) const;
  Round Candidates(const FitSummary& current) const;
  void Refit(Round& round, const FitSummary& current, int number);
  int Select(Round& round, const FitSummary& current, const Model& model, const std::map<std::string, double>& ratio,
             int number);
  DiscoveryStep Step(const Round& round, int best, const FitSummary& current, const std::vector<Finding>& findings,
                     const std::map<std::string, double>& ratio) const;
  void Conclude(DiscoveryResult& result, bool exhausted, const std::map<std::string, double>& ratio) const;

  const FitData& data_;
  const DiscoverOptions& options_;
  const std::function<void(const std::string&)>& progress_;
  const Causality causality_;
  const std::string base_;
  SessionFitOptions session_options_;
  std::optional<HeldOut> current_cv_;          // held-out noise ratios of the current model, once a candidate needs them
  std::map<std::string, int> last_iterations_;  // per term, its refit's in the round before
  double candidate_seconds_ = 0.0, cv_seconds_ = 0.0;
};

// Why a candidate is not worth its refit (nullopt: it is): its size score's first-order fall of
// -2 log-likelihood, screen_margin times over, does not pay for its new parameters by bic_threshold.
std::optional<std::string> DiscoveryRun::Screened(const TermStart& start, const FitSummary& current) const {
  if (!(options_.screen_margin > 0) || !std::isfinite(start.size_score)) return std::nullopt;
  int added = 0;
  for (int i = 0; i < start.start.size(); ++i)
    if (start.choices[i].estimate && !current.parameters.find(start.start.spec(i).key())) ++added;
  const double cost = options_.bic_threshold + added * std::log(static_cast<double>(std::max(1L, current.observations)));
  const double fall = options_.screen_margin * start.size_score * start.size_score;
  if (fall >= cost) return std::nullopt;
  return fmt::format("screened out: size score t {:+.2f}, {} x t^2 = {:.1f} below the {:.1f} its parameters cost",
                     start.size_score, options_.screen_margin, fall, cost);
}

// A candidate: the current fit's values and estimated set, plus the new term's own parameters (sizes
// and shapes estimated, from where the located mismatch puts them: StartWithTerm).
FitSummary DiscoveryRun::FitCandidate(const std::string& term, const Model& model, TermStart term_start,
                                      const FitSummary& previous) const {
  const EstimatorOptions& estimator = session_options_.estimator;
  const std::string& composition = model.composition();
  const ParameterSet& start = term_start.start;
  const std::vector<ParameterChoice>& choices = term_start.choices;
  const Estimator fitter(model, estimator);
  FitSummary fit = fitter.Fit(data_.experiments, start, choices, data_.issues);
  // Only a stalled candidate that already explains something (its BIC below the current one by the
  // threshold) is worth the second try: the others would be refused anyway.
  if (fit.converged || !fit.IsSolutionUsable() || !(fit.bic - previous.bic < -options_.bic_threshold)) return fit;
  // A candidate can stall on its way from the current fit's values when that fit is itself far off
  // (an unconverged baseline beside a plain end stop): go on from where it stalled (fresh
  // sensitivities and damping), and else fit from the data's own starting values as `strut
  // identify` does. The converged fit with the higher likelihood is kept.
  const Stopwatch retry_watch;
  std::vector<FitSummary> tries{fitter.Fit(data_.experiments, fit.parameters, choices, data_.issues)};
  if (!tries.front().converged) {
    SessionFitOptions own = session_options_;
    own.composition = composition;
    tries.push_back(FitPrepared(data_, model, own).summary);
  }
  for (const FitSummary& t : tries)
    if (t.converged && (!fit.converged || t.loglik > fit.loglik)) fit = t;
  spdlog::debug("candidate {}: stalled from the current fit; {} (timing: {} more fits, {:.2f} s)", term,
                fit.converged ? "converged on a second try" : "not converged on a second try either", tries.size(),
                retry_watch.Seconds());
  return fit;
}

Round DiscoveryRun::Candidates(const FitSummary& current) const {
  const Model model = Model::Build(current.model, causality_);
  Round round;
  for (const TermEntry& entry : Catalogue()) {
    if (entry.locus.empty() || model.has_term(entry.name)) continue;
    const std::string composition = current.model + "+" + entry.name;
    try {
      Model::Build(composition, causality_);
      round.candidates.emplace_back(entry.name, composition);
    } catch (const ModelError& e) {
      spdlog::debug("candidate {} left out: {}", entry.name, e.what());
    }
  }
  round.results.resize(round.candidates.size());
  round.fits.resize(round.candidates.size());
  round.held_out.resize(round.candidates.size());
  return round;
}

void DiscoveryRun::Refit(Round& round, const FitSummary& current, int number) {
  const auto& candidates = round.candidates;
  std::vector<double> seconds(candidates.size());
  const Stopwatch round_watch;
  // A thread takes the next candidate as it finishes one (refits differ in length several times),
  // the longest first as far as the last round tells (its iterations), so that a long one does not
  // start last. Only the order of the work changes: each result has its own slot.
  std::vector<int> queue(candidates.size());
  std::iota(queue.begin(), queue.end(), 0);
  const auto expected = [&](int c) {
    const auto it = last_iterations_.find(candidates[c].first);
    return it == last_iterations_.end() ? INT_MAX : it->second;
  };
  std::stable_sort(queue.begin(), queue.end(), [&](int a, int b) { return expected(a) > expected(b); });
  ParallelFor(static_cast<int>(candidates.size()), options_.threads, [&](int k) {
    const int c = queue[k];
    const Stopwatch watch;
    CandidateFit& r = round.results[c];
    r.term = candidates[c].first;
    try {
      const Model model = Model::Build(candidates[c].second, causality_);
      std::vector<std::string> log;
      TermStart start = StartWithTerm(model, r.term, current, &log);
      for (const std::string& line : log) spdlog::debug("candidate {}: {}", r.term, line);
      r.size_score = start.size_score;
      if (const std::optional<std::string> why = Screened(start, current)) {
        r.screened = true;
        r.delta_bic = NAN;
        r.error = r.verdict = *why;
        seconds[c] = watch.Seconds();
        return;
      }
      round.fits[c] = FitCandidate(r.term, model, std::move(start), current);
      r.ok = round.fits[c].IsSolutionUsable() && round.fits[c].converged;
      if (!r.ok) r.error = round.fits[c].VerdictText();
      r.delta_bic = round.fits[c].bic - current.bic;
      r.noise_ratio = PooledNoiseRatio(round.fits[c]);
    } catch (const EstimationError& e) {  // the candidate does not fit: reported, the round goes on
      r.error = e.what();
    } catch (const PeriodicSolverError& e) {
      r.error = e.what();
    } catch (const std::invalid_argument& e) {  // its model or starting values cannot be built
      r.error = e.what();
    }
    seconds[c] = watch.Seconds();
  });
  const double refits_seconds = round_watch.Seconds();
  for (std::size_t c = 0; c < candidates.size(); ++c) last_iterations_[candidates[c].first] = round.fits[c].iterations;
  candidate_seconds_ += refits_seconds;
  for (std::size_t c = 0; c < candidates.size(); ++c)
    spdlog::debug("timing: round {} candidate {} {:.2f} s ({} iterations)", number, candidates[c].first, seconds[c],
                  round.fits[c].iterations);
  spdlog::debug("timing: round {} candidates {:.2f} s wall, {:.2f} s summed", number, refits_seconds,
                std::accumulate(seconds.begin(), seconds.end(), 0.0));
}

// Candidates by BIC; the best that also brings the off channels down and predicts experiments left
// out of its fit better than the current model is kept. Returns its index, or -1.
int DiscoveryRun::Select(Round& round, const FitSummary& current, const Model& model,
                         const std::map<std::string, double>& ratio, int number) {
  std::vector<CandidateFit>& results = round.results;
  std::vector<std::size_t> order;
  for (std::size_t c = 0; c < results.size(); ++c) {
    CandidateFit& r = results[c];
    if (r.screened) {
      continue;  // its verdict says why
    } else if (!r.ok) {
      r.verdict = "no converged fit";
    } else if (r.delta_bic > -options_.bic_threshold) {
      r.verdict = fmt::format("BIC does not fall by {}", options_.bic_threshold);
    } else if (MeanRatio(r.noise_ratio) - 1.0 > options_.min_improvement * (MeanRatio(ratio) - 1.0) ||
               !FallsBeyondNoise(current, round.fits[c])) {
      r.verdict = "noise ratio barely falls";
    } else {
      order.push_back(c);
    }
  }
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return results[a].delta_bic < results[b].delta_bic; });
  for (const std::size_t c : order) {
    if (options_.cv_folds == 0) return static_cast<int>(c);
    // The current model's folds beside the first candidate's, when it has none yet.
    const Stopwatch cv_watch;
    const Model candidate_model = Model::Build(round.candidates[c].second, causality_);
    std::vector<CrossValidation> wanted{{&candidate_model, &round.fits[c]}};
    if (!current_cv_) wanted.push_back({&model, &current});
    const std::vector<HeldOut> cv =
        CrossValidate(data_, wanted, session_options_.estimator, options_.cv_folds, options_.threads);
    round.held_out[c] = cv[0];
    results[c].cv_ratio = cv[0].median;
    if (!current_cv_) current_cv_ = cv[1];
    cv_seconds_ += cv_watch.Seconds();
    spdlog::debug("timing: round {} cross-validation {:.2f} s", number, cv_watch.Seconds());
    spdlog::info("  {:<20} cross-validated noise ratio {:.3f} against {:.3f}", results[c].term, results[c].cv_ratio,
                 current_cv_->median);
    if (PredictsHeldOutBetter(cv[0], *current_cv_, options_)) return static_cast<int>(c);
    results[c].verdict = "does not predict left-out experiments better";
  }
  return -1;
}

DiscoveryStep DiscoveryRun::Step(const Round& round, int best, const FitSummary& current,
                                 const std::vector<Finding>& findings, const std::map<std::string, double>& ratio) const {
  const CandidateFit& kept = round.results[best];
  DiscoveryStep step;
  step.term = kept.term;
  step.delta_bic = kept.delta_bic;
  step.noise_before = ratio;
  step.noise_after = kept.noise_ratio;
  step.cv_before = current_cv_ ? current_cv_->median : NAN;
  step.cv_after = kept.cv_ratio;
  step.candidates = round.results;
  const TermEntry& entry = CatalogueEntry(step.term);
  step.evidence = entry.signature;
  for (const Finding& f : findings)
    if (f.locus == entry.locus) {
      step.evidence += "; " + f.detail;
      break;
    }
  const FitSummary& chosen = round.fits[best];
  for (int i = 0; i < chosen.parameters.size(); ++i)
    if (!current.parameters.find(chosen.parameters.spec(i).key()) && chosen.estimates[i].estimated)
      step.parameters.emplace_back(chosen.parameters.spec(i).key(), chosen.parameters.value(i));
  return step;
}

void DiscoveryRun::Conclude(DiscoveryResult& result, bool exhausted, const std::map<std::string, double>& ratio) const {
  const bool at_floor = AtNoiseFloor(result.final_fit);
  if (!at_floor) {
    for (const Finding& f : LocateMismatch(result.final_fit))
      if (f.score > 5.0) result.unexplained.push_back(f);
  }
  std::string ratios;
  for (const auto& [c, r] : PooledNoiseRatio(result.baseline)) ratios += fmt::format(" {} {:.2f}", c, r);
  if (result.nothing_missing) {
    result.conclusion = fmt::format("{} explains the data to the noise floor (noise ratios{}): nothing is missing.",
                                    base_, ratios);
    return;
  }
  std::string added;
  for (const auto& t : result.missing) added += (added.empty() ? "" : ", ") + t;
  std::string after;
  for (const auto& [c, r] : ratio) after += fmt::format(" {} {:.2f}", c, r);
  result.conclusion = fmt::format(
      "{} left residuals above the noise floor (noise ratios{}). {} Final model {} (noise ratios{}{}).{}", base_, ratios,
      added.empty() ? "No catalogue term explains them." : "Missing: " + added + ".", result.final_model, after,
      at_floor ? ", at the noise floor" : ", still above the noise floor",
      result.unexplained.empty()
          ? ""
          : (exhausted ? " What is left matches no catalogue term: "
                       : fmt::format(" Stopped after {} terms; the strongest feature left: ", options_.max_terms)) +
                result.unexplained.front().detail + ".");
}

DiscoveryResult DiscoveryRun::Run() {
  const Stopwatch total_watch;
  DiscoveryResult result;
  bool exhausted = false;  // stopped because no candidate qualified (not because of max_terms)
  Say(fmt::format("fitting the baseline {} (every parameter the data can determine)", base_));
  const Stopwatch baseline_watch;
  result.baseline = FitPrepared(data_, Model::Build(base_, causality_), session_options_).summary;
  const double baseline_seconds = baseline_watch.Seconds();
  spdlog::debug("timing: baseline {} {:.2f} s ({} iterations)", base_, baseline_seconds, result.baseline.iterations);
  result.mismatch = LocateMismatch(result.baseline);
  FitSummary current = result.baseline;
  std::map<std::string, double> ratio = PooledNoiseRatio(current);
  result.nothing_missing = AtNoiseFloor(result.baseline);
  if (!result.baseline.converged) Say("the baseline fit did not converge: " + result.baseline.VerdictText());

  for (int number = 1; number <= options_.max_terms && !AtNoiseFloor(current); ++number) {
    const std::vector<Finding> findings = LocateMismatch(current);
    const Model model = Model::Build(current.model, causality_);
    Round round = Candidates(current);
    Say(fmt::format("round {}: {} candidates refitted, {} at a time", number, round.candidates.size(), options_.threads));
    Refit(round, current, number);
    for (CandidateFit& c : round.results) {
      const TermEntry& entry = CatalogueEntry(c.term);
      for (const Finding& f : findings)
        if (f.locus == entry.locus) c.evidence = std::max(c.evidence, f.score);
    }
    const int best = Select(round, current, model, ratio, number);
    for (const CandidateFit& c : round.results)
      spdlog::info("  {:<20} ΔBIC {:>12.1f}  worst noise ratio {:8.2f}  evidence {:6.1f}  {}", c.term, c.delta_bic,
                   WorstRatio(c.noise_ratio), c.evidence, c.ok ? c.verdict : c.error);
    if (best < 0) {
      Say("no candidate improves the fit beyond what its parameters cost and predicts left-out experiments better");
      exhausted = true;
      break;
    }
    round.results[best].verdict = "kept";
    DiscoveryStep step = Step(round, best, current, findings, ratio);
    Say(fmt::format("added {}: ΔBIC {:+.1f}; {}", step.term, step.delta_bic, step.evidence));
    result.missing.push_back(step.term);
    result.steps.push_back(std::move(step));
    current = round.fits[best];
    current_cv_ = round.held_out[best];
    ratio = PooledNoiseRatio(current);
  }

  result.final_model = current.model;
  result.final_fit = current;
  Conclude(result, exhausted, ratio);
  spdlog::debug("timing: discover {:.2f} s: baseline {:.2f} s, candidates {:.2f} s, cross-validation {:.2f} s",
                total_watch.Seconds(), baseline_seconds, candidate_seconds_, cv_seconds_);
  // The conclusion is the result, which the caller prints as data (stdout); logging it as well
  // would show it twice on a terminal.
  spdlog::debug("{}", result.conclusion);
  if (progress_) progress_(result.conclusion);
  return result;
}

}  // namespace

DiscoveryResult Discover(const FitData& data, const SessionFitOptions& fit_options, const DiscoverOptions& options,
                         const std::function<void(const std::string&)>& progress) {
  std::string error;
  if (!options.IsValid(&error) || !fit_options.IsValid(&error)) throw std::invalid_argument("discover options: " + error);
  return DiscoveryRun(data, fit_options, options, progress).Run();
}

}  // namespace strut::ident
