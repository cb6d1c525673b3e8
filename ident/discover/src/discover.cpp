#include "strut/ident/discover.h"

#include <algorithm>
#include <chrono>
#include <climits>
#include <cmath>
#include <deque>
#include <fmt/format.h>
#include <numeric>
#include <numbers>
#include <optional>
#include <spdlog/spdlog.h>

#include "strut/ident/parallel.h"
#include "strut/ident/initial_values.h"
#include "strut/ident/catalogue.h"
#include "strut/ident/term_start.h"

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
  if (max_discrepancy_functions < 0 || discrepancy_refits < 1)
    return fail("max_discrepancy_functions must not be negative and discrepancy_refits at least 1");
  if (!(ambiguity_bic_margin >= 0) || !(ambiguity_correlation > 0 && ambiguity_correlation <= 1))
    return fail("ambiguity_bic_margin must not be negative and ambiguity_correlation must be in (0, 1]");
  if (test_space && !test_space->IsValid(error)) return false;
  for (const std::string& term : leave_out)
    if (std::none_of(Catalogue().begin(), Catalogue().end(), [&](const TermEntry& e) { return e.name == term; }))
      return fail(fmt::format("leave_out: '{}' is not a catalogue term", term));
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

// The families of the discrepancy's functions, by coefficient index (DiscrepancyLibrary).
bool IsDamping(int index) { return index >= 70 && index <= 76; }
bool IsStiffness(int index) { return index == 79 || index == 80; }

double Median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

// Where the matrix goes: the stroke range, the middle static position, the median and largest peak
// rate, and the measured pressure against the stroke (a quadratic through all the averaged data).
struct MatrixReach {
  double q_lo = INFINITY, q_hi = -INFINITY, q_mid = NAN, v_typical = NAN, v_max = 0.0;
  double static_lo = NAN, static_hi = NAN;
  double p_lo = NAN, p_hi = NAN;  // the lowest and highest pressure measured
  Eigen::Vector3d pressure = Eigen::Vector3d::Zero();  // p(q) = c0 + c1 q + c2 q^2
  double PressureAt(double q) const { return pressure[0] + q * (pressure[1] + q * pressure[2]); }
};

MatrixReach Reach(const FitSummary& fit) {
  MatrixReach m;
  std::vector<double> statics, peaks;
  std::vector<double> qs, ps;
  for (const ExperimentFit& e : fit.experiments) {
    const auto stroke = e.measured.find("stroke");
    if (stroke == e.measured.end() || stroke->second.size() == 0) continue;
    m.q_lo = std::min(m.q_lo, stroke->second.minCoeff());
    m.q_hi = std::max(m.q_hi, stroke->second.maxCoeff());
    statics.push_back(e.static_position);
    const double peak = 2.0 * std::numbers::pi * e.frequency * e.amplitude;
    peaks.push_back(peak);
    m.v_max = std::max(m.v_max, peak);
    if (const auto p = e.measured.find("pressure"); p != e.measured.end() && p->second.size() == stroke->second.size())
      for (Eigen::Index i = 0; i < p->second.size(); ++i) qs.push_back(stroke->second[i]), ps.push_back(p->second[i]);
  }
  if (!ps.empty()) {
    m.p_lo = *std::min_element(ps.begin(), ps.end());
    m.p_hi = *std::max_element(ps.begin(), ps.end());
  }
  m.q_mid = Median(statics);
  if (!statics.empty()) {
    m.static_lo = *std::min_element(statics.begin(), statics.end());
    m.static_hi = *std::max_element(statics.begin(), statics.end());
  }
  m.v_typical = Median(peaks);
  if (qs.size() >= 3) {
    Eigen::MatrixXd a(qs.size(), 3);
    Eigen::VectorXd b(qs.size());
    for (std::size_t i = 0; i < qs.size(); ++i) a.row(i) << 1.0, qs[i], qs[i] * qs[i], b[i] = ps[i];
    m.pressure = a.colPivHouseholderQr().solve(b);
  }
  return m;
}

std::string Times(double ratio) { return fmt::format("{:.2g} times", ratio); }

}  // namespace

EmpiricalDiscrepancy DescribeDiscrepancy(const FitSummary& fit) {
  EmpiricalDiscrepancy d;
  const ParameterSet& p = fit.parameters;
  std::vector<int> selected;  // positions of the estimated coefficients
  for (const DiscrepancyFunction& f : DiscrepancyLibrary()) {
    const int position = p.position_of_index(f.index);
    if (position < 0 || position >= static_cast<int>(fit.estimates.size()) || !fit.estimates[position].estimated) continue;
    selected.push_back(position);
    const std::string& resembles =
        p.value(position) < 0.0 && !f.resembles_when_negative.empty() ? f.resembles_when_negative : f.resembles;
    d.functions.push_back({f.index, f.name, f.shape, resembles, p.value(position), fit.estimates[position].sd});
    if (!resembles.empty() && std::find(d.resembles.begin(), d.resembles.end(), resembles) == d.resembles.end())
      d.resembles.push_back(resembles);
  }
  if (d.functions.empty()) return d;
  const MatrixReach m = Reach(fit);
  if (!std::isfinite(m.q_mid) || !(m.v_typical > 0)) return d;
  const Model model = Model::Build(fit.model, Causality::kStrokeInput);
  const auto has = [&](auto&& family) {
    return std::any_of(d.functions.begin(), d.functions.end(), [&](const DiscrepancyTerm& f) { return family(f.index); });
  };
  const auto value_of = [&](int index) {
    const int position = p.position_of_index(index);
    return position >= 0 ? p.value(position) : 0.0;
  };
  // The model's force at stroke q and rate v with the gas at the measured pressure there (the force
  // balance's residual with the force unknown 0): with the coefficients of one family as fitted and
  // the rest of the discrepancy at 0, less the same without the discrepancy, is that family's force.
  const int m_count = model.unknown_count();
  const auto force = [&](const std::vector<double>& theta, double q, double v) {
    std::vector<double> x(m_count, 0.0), xd(m_count, 0.0), xdd(m_count, 0.0), r(m_count, 0.0);
    for (int j = 1; j < m_count; ++j) {
      const StateSpec spec = model.unknown_spec(j);
      x[j] = spec.name == "pressure" ? m.PressureAt(q) : spec.name == "temperature" ? -value_of(17) : spec.typical_value;
    }
    model.Residual<double>(x, xd, xdd, q, v, 0.0, model.AtExperiment(theta, {0.0, m.q_mid}), r);
    return r[0];
  };
  std::vector<double> without = p.values();
  for (int position : selected) without[position] = 0.0;
  const auto family_force = [&](auto&& family, double q, double v) {
    std::vector<double> with = without;
    for (const DiscrepancyTerm& f : d.functions)
      if (family(f.index)) with[p.position_of_index(f.index)] = f.value;
    return force(with, q, v) - force(without, q, v);
  };
  const auto any = [](int) { return true; };
  const double v = m.v_typical;
  const std::string at = fmt::format("at {:.2f} m/s", v);
  const std::string over = fmt::format("from {:.0f} mm to {:.0f} mm of stroke", m.q_lo * 1e3, m.q_hi * 1e3);

  if (has(IsDamping)) {
    // The whole damping force's size in each direction: the orifice's (and a viscous term's) plus
    // the discrepancy's damping functions.
    const double viscous = value_of(18);
    const double base = value_of(3) * v * v + viscous * v;
    const auto compression = [&](double q) { return base + family_force(IsDamping, q, v); };
    const auto extension = [&](double q) { return base - family_force(IsDamping, q, -v); };
    if (has([](int i) { return i == 70 || i == 72 || i == 75; })) {
      const double ratio = extension(m.q_mid) / compression(m.q_mid);
      d.dependence.push_back(ratio >= 1.0 ? fmt::format("damping in extension {} compression {}", Times(ratio), at)
                                          : fmt::format("damping in compression {} extension {}", Times(1.0 / ratio), at));
    }
    if (has([](int i) { return i == 71 || i == 72 || i == 73; })) {
      const double c = compression(m.q_hi) / compression(m.q_lo), e = extension(m.q_hi) / extension(m.q_lo);
      const auto trend = [&](double g) { return g >= 1.0 ? "grows " + Times(g) : "falls to " + fmt::format("{:.2g}", g); };
      d.dependence.push_back(std::abs(c - e) < 0.1 * std::max(c, e)
                                 ? fmt::format("damping {} {} {}", trend(0.5 * (c + e)), over, at)
                                 : fmt::format("damping in compression {}, in extension {}, {} {}", trend(c), trend(e),
                                               over, at));
    }
    if (has([](int i) { return i == 74; }))
      d.dependence.push_back(fmt::format("damping linear in the rate, {:.0f} N s/m",
                                         family_force([](int i) { return i == 74; }, m.q_mid, v) / v));
    if (has([](int i) { return i == 76; }))
      d.dependence.push_back(fmt::format("a force in phase with the rate that grows with the pressure: {:+.0f} N {} at "
                                         "{:.1f} MPa, {:+.0f} N at {:.1f} MPa",
                                         family_force([](int i) { return i == 76; }, m.q_hi, v), at,
                                         m.PressureAt(m.q_hi) * 1e-6, family_force([](int i) { return i == 76; }, m.q_lo, v),
                                         m.PressureAt(m.q_lo) * 1e-6));
  }
  for (const DiscrepancyTerm& f : d.functions) {
    // Sliding friction (past the reversals, atan at +-pi/2) is A pi/2 (1 + c) in compression and
    // A pi/2 (1 - c) in extension for friction-direction, A pi/2 (1 + c q / 0.1 m) for friction-stroke.
    if (f.index == 77)
      d.dependence.push_back(fmt::format("friction in compression {} extension", Times((1.0 + f.value) / (1.0 - f.value))));
    if (f.index == 78)
      d.dependence.push_back(fmt::format("friction at the deepest stroke {} that at the least, {}",
                                         Times((1.0 + f.value * m.q_hi / 0.1) / (1.0 + f.value * m.q_lo / 0.1)), over));
  }
  if (has(IsStiffness))
    d.dependence.push_back(fmt::format("a force of the stroke alone beyond the gas law, {:+.0f} N at {:.0f} mm against "
                                       "{:+.0f} N at {:.0f} mm",
                                       family_force(IsStiffness, m.q_hi, 0.0), m.q_hi * 1e3,
                                       family_force(IsStiffness, m.q_lo, 0.0), m.q_lo * 1e3));
  for (const DiscrepancyTerm& f : d.functions) {
    const double s_hi = m.q_hi / 0.1;
    if (f.index == 81)
      d.dependence.push_back(fmt::format("a force level moving by {:+.0f} N from the session's first experiment to its last",
                                         f.value * value_of(4) * 1e6));
    else if (f.index == 82 || f.index == 83)
      d.dependence.push_back(fmt::format("a gas volume {:+.2f} % of the charge volume off the linear volume law at {:.0f} mm",
                                         100.0 * f.value * std::pow(s_hi, f.index == 82 ? 2 : 3), m.q_hi * 1e3));
    else if (f.index == 84)
      d.dependence.push_back(fmt::format("free gas changing with the pressure, {:+.2f} % of the charge per 10 MPa",
                                         100.0 * f.value));
    else if (f.index == 85)
      d.dependence.push_back(fmt::format("free gas changing by {:+.2f} % of the charge from the first experiment to the last",
                                         100.0 * f.value));
    else if (f.index == 90)
      d.dependence.push_back(
          f.value >= 0.0
              ? fmt::format("a gas volume growing with the pressure, {:.2f} % of the charge volume per 10 MPa", 100.0 * f.value)
              : fmt::format("a gas volume shrinking as the pressure rises, {:.2f} % of the charge volume per 10 MPa: the "
                            "gas stiffer at high pressure than the gas law holds",
                            -100.0 * f.value));
    else if (f.index == 99)
      // The free gas, and so the pressure, per 10 K of heating at the highest pressure measured.
      d.dependence.push_back(fmt::format("the gas pressure following its temperature {} than the gas law holds, the more "
                                         "so the higher the pressure: {:.2f} % {} per 10 K of heating at {:.1f} MPa",
                                         f.value >= 0.0 ? "more" : "less",
                                         std::abs(100.0 * f.value * (m.p_hi / 1e7) * (10.0 / 293.15)),
                                         f.value >= 0.0 ? "more" : "less", m.p_hi * 1e-6));
  }
  if (has([](int i) { return i == 91; }) && m.p_lo > 0) {
    // The wall's heat conductance relative to theta16's, 1 + c91 ((p / 2 MPa)^n - 1) / n, n = theta92,
    // at the lowest and highest pressure measured.
    const double exponent = value_of(92);
    const auto conductance = [&](double pressure) {
      const double ln_x = std::log(pressure / 2e6);
      return 1.0 + value_of(91) * (std::abs(exponent) < 1e-6 ? ln_x : std::expm1(exponent * ln_x) / exponent);
    };
    const int position = p.position_of_index(92);
    const double sd = position >= 0 && position < static_cast<int>(fit.estimates.size()) ? fit.estimates[position].sd : NAN;
    const double growth = conductance(m.p_hi) / conductance(m.p_lo);
    d.dependence.push_back(fmt::format("heat flowing through the wall {} readily at high pressure: the wall's heat "
                                       "conductance {} as high at {:.1f} MPa as at {:.1f} MPa, its change as the "
                                       "pressure to the power {:.2f} (sd {:.2f}){}",
                                       growth >= 1.0 ? "more" : "less", Times(growth), m.p_hi * 1e-6, m.p_lo * 1e-6,
                                       exponent, sd,
                                       growth >= 1.0 ? ""
                                                     : "; heat transfer grows with the gas density, so this rather "
                                                       "says that the thermal loop grows with the pressure, as a gas "
                                                       "whose pressure follows its temperature more at high pressure "
                                                       "(a real gas) makes it"));
  }
  if (has([](int i) { return i == 93 || i == 94 || i == 95; })) {
    // The low-speed functions' force over the sliding friction (theta8 + theta9 p) atan(theta10 q')
    // at the same rate: their excess, whatever their widths; the speed at which half of it is left.
    const auto low_speed = [](int i) { return i == 93 || i == 94 || i == 95; };
    const double sliding = value_of(8) + value_of(9) * m.PressureAt(m.q_mid);
    const auto excess = [&](double speed) {
      return family_force(low_speed, m.q_mid, speed) / (sliding * std::atan(value_of(10) * speed));
    };
    const double peak = excess(1e-5);
    double half = 1e-5;
    while (half < 0.05 && std::abs(excess(half)) > 0.5 * std::abs(peak)) half += 1e-4;
    d.dependence.push_back(fmt::format("friction {:+.0f} % of the sliding friction near the velocity reversals, half of "
                                       "that left at {:.1f} mm/s",
                                       100.0 * peak, half * 1e3));
  }
  if (has([](int i) { return i == 96 || i == 98; })) {
    // The contact as the model gives it, pushing toward compression: its force at rest at the least
    // stroke the matrix reached; its stiffness, and that of its rate part at 0.1 m/s of extension
    // into it, over the millimetre from 1 to 2 mm past where it sets in.
    const double position = value_of(97);
    const auto contact = [&](int index, double q, double rate) {
      return -family_force([index](int i) { return i == index; }, q, rate);
    };
    const auto per_mm = [&](int index, double rate) {  // two points a millimetre apart
      return contact(index, position - 2e-3, rate) - contact(index, position - 1e-3, rate);
    };
    const double rate_per_mm = per_mm(98, -0.1);
    d.dependence.push_back(fmt::format("a contact pushing toward compression past {:.1f} mm of stroke: {:.0f} N at {:.1f} "
                                       "mm at rest, a stiffness of {:.0f} N/mm{}",
                                       position * 1e3, contact(96, m.q_lo, 0.0), m.q_lo * 1e3, per_mm(96, 0.0),
                                       rate_per_mm == 0.0 ? ""
                                                          : fmt::format(", and {:+.0f} N/mm more per 0.1 m/s of "
                                                                        "extension into it",
                                                                        rate_per_mm)));
  }
  // The static functions against the middle static position: the levels of the lowest and the
  // highest static-position group (the global levels theta11 and theta5 hold the middle one).
  const auto static_level = [&](int linear, int squared, double z) {
    const double s = z / 0.1, s_mid = m.q_mid / 0.1;
    return value_of(linear) * (s - s_mid) + value_of(squared) * (s * s - s_mid * s_mid);
  };
  const auto static_sentence = [&](const char* what, double scale, const char* unit, int precision, int linear,
                                   int squared) {
    return fmt::format("{} changing with the experiment's static position: {:+.{}f} {} at {:.0f} mm and {:+.{}f} {} at "
                       "{:.0f} mm against the level at {:.0f} mm",
                       what, scale * static_level(linear, squared, m.static_lo), precision, unit, m.static_lo * 1e3,
                       scale * static_level(linear, squared, m.static_hi), precision, unit, m.static_hi * 1e3,
                       m.q_mid * 1e3);
  };
  if (has([](int i) { return i == 86 || i == 87; }) && std::isfinite(m.static_lo))
    d.dependence.push_back(static_sentence("a force level", value_of(4) * 1e6, "N", 0, 86, 87));
  if (has([](int i) { return i == 88 || i == 89; }) && std::isfinite(m.static_lo))
    d.dependence.push_back(static_sentence("free gas", 100.0, "% of the charge", 2, 88, 89));
  // The curves: the missing force (every force function) against the rate at the middle static
  // position, and against the stroke in each direction at the median peak rate.
  EmpiricalDiscrepancy::Curve rate{"against stroke rate (m/s) at the middle static position", {}, {}};
  for (int k = -20; k <= 20; ++k) {
    const double r = m.v_max * k / 20.0;
    rate.x.push_back(r);
    rate.force.push_back(family_force(any, m.q_mid, r) - family_force(any, m.q_mid, 0.0));
  }
  d.curves.push_back(std::move(rate));
  for (const double sign : {1.0, -1.0}) {
    EmpiricalDiscrepancy::Curve stroke{fmt::format("against stroke (m), {} at {:.2f} m/s", sign > 0 ? "compression" : "extension", v),
                                       {}, {}};
    for (int k = 0; k <= 20; ++k) {
      const double q = m.q_lo + (m.q_hi - m.q_lo) * k / 20.0;
      stroke.x.push_back(q);
      stroke.force.push_back(family_force(any, q, sign * v));
    }
    d.curves.push_back(std::move(stroke));
  }
  return d;
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

// Whether some channel's ratio falls from `current` to `candidate` by more than noise moves it (the
// floor test's z times the ratio's sd, which is how far the channel's limit lies above 1), or a
// channel above its noise floor comes down to it: near the floor the first asks the candidate to
// take away more misfit than is left, and would refuse a term the BIC and the held-out test support.
bool FallsBeyondNoise(const FitSummary& current, const FitSummary& candidate) {
  for (const FitChannel& c : current.channels) {
    const double margin = std::isfinite(c.noise_ratio_sd) ? c.noise_floor_limit - 1.0 : 0.0;
    for (const FitChannel& k : candidate.channels)
      if (k.name == c.name && (c.noise_ratio - k.noise_ratio > margin || (c.AboveNoiseFloor() && !k.AboveNoiseFloor())))
        return true;
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

// The discrepancy of a start holds the functions `in` (coefficient indices) and no other: each
// other function's coefficient at 0 and fixed; a shape estimated where a function in holds it (a
// contact's position serves its force and its rate part), fixed where none does. The coefficients
// of the functions in keep their choices.
void KeepOnlyFunctions(const Model& model, const std::vector<int>& in, TermStart& start) {
  const auto held = [&](int index) { return std::find(in.begin(), in.end(), index) != in.end(); };
  for (const DiscrepancyFunction& f : DiscrepancyLibrary()) {
    const int position = model.defaults().position_of_index(f.index);
    if (position < 0 || held(f.index)) continue;
    start.start.set(model.defaults().spec(position).key(), 0.0);
    start.choices[position] = ParameterChoice{};
  }
  for (const DiscrepancyFunction& f : DiscrepancyLibrary()) {
    const int shape = f.shape_index ? model.defaults().position_of_index(f.shape_index) : -1;
    if (shape < 0) continue;
    const bool used = std::any_of(DiscrepancyLibrary().begin(), DiscrepancyLibrary().end(), [&](const DiscrepancyFunction& g) {
      return g.shape_index == f.shape_index && held(g.index) && model.defaults().position_of_index(g.index) >= 0;
    });
    // Its shape is the data's to say: estimated without a prior.
    if (!used)
      start.choices[shape] = ParameterChoice{};
    else if (!start.choices[shape].estimate)
      start.choices[shape] = ParameterChoice{.estimate = true, .prior_sd = std::nullopt};
  }
}

// The discrepancy functions a fit estimates (coefficient indices).
std::vector<int> EstimatedFunctions(const FitSummary& fit) {
  std::vector<int> out;
  for (const DiscrepancyFunction& f : DiscrepancyLibrary())
    if (const int p = fit.parameters.position_of_index(f.index);
        p >= 0 && p < static_cast<int>(fit.estimates.size()) && fit.estimates[p].estimated)
      out.push_back(f.index);
  return out;
}

constexpr const char* kNotBetterHeldOut = "does not predict left-out experiments better";

// One round's candidates: each term that composes with the current model, its refit and its verdict.
struct Round {
  std::vector<std::pair<std::string, std::string>> candidates;  // term, composition
  // Empirical rounds: per candidate the discrepancy coefficient's index and its start, worked out
  // before the refits (only the largest size scores are refitted).
  std::vector<int> function;
  std::vector<std::optional<TermStart>> starts;
  std::vector<CandidateFit> results;
  std::vector<FitSummary> fits;
  std::vector<HeldOut> held_out;  // per candidate, its held-out ratios where it was cross-validated
  std::vector<bool> refitted;     // per candidate, whether Refit has fitted it
  // Empirical rounds: the candidates screened out by their size score's rank, largest score first.
  std::deque<std::size_t> waiting;
};

// A round's candidates and their verdicts, one line each.
void LogCandidates(const Round& round) {
  for (const CandidateFit& c : round.results)
    spdlog::info("  {:<20} ΔBIC {:>12.1f}  worst noise ratio {:8.2f}  evidence {:6.1f}  {}", c.term, c.delta_bic,
                 WorstRatio(c.noise_ratio), c.evidence, c.ok ? c.verdict : c.error);
}

// A kept catalogue term's rivals: the round's other candidates that passed the BIC and noise-ratio
// rules and were not refused by the held-out test, with their fits (the current model plus the rival).
struct KeptWithRivals {
  int step = 0;
  std::string kept;
  std::vector<std::pair<std::string, FitSummary>> rivals;
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
  FitSummary FitCandidate(const std::string& term, const Model& model, TermStart start, const FitSummary& previous,
                          int function) const;
  FitSummary RefitFromTheCurrentFit(const std::string& term, int function, const Model& model, TermStart nested,
                                    const FitSummary& previous, FitSummary stalled) const;
  std::optional<std::string> Screened(const TermStart& start, const FitSummary& current) const;
  Round Candidates(const FitSummary& current) const;
  Round EmpiricalCandidates(const FitSummary& current, std::string_view spare = {}) const;
  void Refit(Round& round, const FitSummary& current, int number);
  int Select(Round& round, const FitSummary& current, const Model& model, const std::map<std::string, double>& ratio,
             int number, double bic_below = INFINITY, std::string_view below_what = {});
  std::optional<std::pair<Round, int>> Challenge(const Round& round, int best, const FitSummary& current,
                                                 const Model& model, const std::map<std::string, double>& ratio,
                                                 int number);
  DiscoveryStep Step(const Round& round, int best, const FitSummary& current, const std::vector<Finding>& findings,
                     const std::map<std::string, double>& ratio) const;
  void Conclude(DiscoveryResult& result, bool exhausted, const std::map<std::string, double>& ratio) const;
  bool Advance(int number, bool empirical, FitSummary& current, std::map<std::string, double>& ratio,
               DiscoveryResult& result);
  RivalExplanation CompareRival(const KeptWithRivals& kept, const std::string& rival, const FitSummary& rival_fit,
                                const DiscoveryResult& result) const;
  void FindAmbiguities(DiscoveryResult& result) const;
  bool TakeOutIfUnsupported(const std::string& name, bool empirical, const Model& model, const TermStart& start,
                            const std::string& context, FitSummary& current, std::map<std::string, double>& ratio,
                            DiscoveryResult& result) const;
  void RemoveUnsupportedFunctions(FitSummary& current, std::map<std::string, double>& ratio,
                                  DiscoveryResult& result) const;
  void RemoveUnsupportedTerms(FitSummary& current, std::map<std::string, double>& ratio, DiscoveryResult& result) const;

  const FitData& data_;
  const DiscoverOptions& options_;
  const std::function<void(const std::string&)>& progress_;
  const Causality causality_;
  const std::string base_;
  SessionFitOptions session_options_;
  std::optional<HeldOut> current_cv_;          // held-out noise ratios of the current model, once a candidate needs them
  std::map<std::string, int> last_iterations_;  // per term, its refit's in the round before
  std::vector<KeptWithRivals> kept_with_rivals_;
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
// `function`: the discrepancy coefficient's index of an empirical candidate, 0 for a catalogue term.
FitSummary DiscoveryRun::FitCandidate(const std::string& term, const Model& model, TermStart term_start,
                                      const FitSummary& previous, int function) const {
  const bool empirical = function > 0;
  const EstimatorOptions& estimator = session_options_.estimator;
  const std::string& composition = model.composition();
  const ParameterSet& start = term_start.start;
  const std::vector<ParameterChoice>& choices = term_start.choices;
  const Estimator fitter(model, estimator);
  FitSummary fit = fitter.Fit(data_.experiments, start, choices, data_.issues);
  if (!fit.converged && fit.IsSolutionUsable() && fit.bic > previous.bic)
    return RefitFromTheCurrentFit(term, function, model, term_start, previous, std::move(fit));
  // Only a stalled candidate that already explains something (its BIC below the current one by the
  // threshold) is worth the second try: the others would be refused anyway.
  if (fit.converged || !fit.IsSolutionUsable() || !(fit.bic - previous.bic < -options_.bic_threshold)) return fit;
  // A candidate can stall on its way from the current fit's values when that fit is itself far off
  // (an unconverged baseline beside a plain end stop): go on from where it stalled (fresh
  // sensitivities and damping), and else fit from the data's own starting values as `strut
  // identify` does. The converged fit with the higher likelihood is kept.
  const Stopwatch retry_watch;
  std::vector<FitSummary> tries{fitter.Fit(data_.experiments, fit.parameters, choices, data_.issues)};
  // (An empirical candidate's estimated set is discovery's choice: the data's own start would fit
  // the whole library.)
  if (!tries.front().converged && !empirical) {
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

// A candidate that stalled worse than the current model started too far from it: the located start
// put the size where the model's response is far from linear (a real gas on a gas law that the
// heat balance has just bent), and the line search found no way back. With its sizes at 0 the
// candidate is the current model exactly, so a fit from there cannot end worse; it is kept when it
// converges. An empirical candidate (`function` its coefficient's index) starts with that coefficient
// at 0: a gas function started by its Gauss-Newton step can stall the same way.
FitSummary DiscoveryRun::RefitFromTheCurrentFit(const std::string& term, int function, const Model& model,
                                                TermStart nested, const FitSummary& previous, FitSummary stalled) const {
  for (int i = 0; i < nested.start.size(); ++i)
    if ((nested.start.spec(i).sizes_term && !previous.parameters.find(nested.start.spec(i).key())) ||
        (function > 0 && nested.start.spec(i).index == function))
      nested.start.values()[i] = 0.0;
  const Stopwatch watch;
  FitSummary again = Estimator(model, session_options_.estimator)
                         .Fit(data_.experiments, nested.start, nested.choices, data_.issues);
  spdlog::debug("candidate {}: stalled at ΔBIC {:+.1f} from its located start; from its sizes at 0 {} at ΔBIC {:+.1f} "
                "(timing: {:.2f} s)",
                term, stalled.bic - previous.bic, again.converged ? "converged" : "not converged",
                again.bic - previous.bic, watch.Seconds());
  return again.converged && again.IsSolutionUsable() ? again : stalled;
}

Round DiscoveryRun::Candidates(const FitSummary& current) const {
  const Model model = Model::Build(current.model, causality_);
  Round round;
  for (const TermEntry& entry : Catalogue()) {
    if (entry.locus.empty() || model.has_term(entry.name) ||
        std::find(options_.leave_out.begin(), options_.leave_out.end(), entry.name) != options_.leave_out.end())
      continue;
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
  round.refitted.assign(round.candidates.size(), false);
  round.function.assign(round.candidates.size(), 0);
  round.starts.resize(round.candidates.size());
  return round;
}

// The discrepancy's functions not yet in the current fit, each started by its Gauss-Newton step;
// all but the `discrepancy_refits` largest size scores are screened out before any refit. Functions
// that share the signature of the catalogue term `spare` are not candidates.
Round DiscoveryRun::EmpiricalCandidates(const FitSummary& current, std::string_view spare) const {
  const bool has = Model::Build(current.model, causality_).has_term("discrepancy");
  const std::string composition = has ? current.model : current.model + "+discrepancy";
  const Model model = Model::Build(composition, causality_);
  Round round;
  for (const DiscrepancyFunction& f : DiscrepancyLibrary()) {
    const int position = model.defaults().position_of_index(f.index);
    if (position < 0 || (!spare.empty() && f.resembles == spare)) continue;
    if (const auto p = current.parameters.find(model.defaults().spec(position).key()); p && current.estimates[*p].estimated)
      continue;
    round.candidates.emplace_back("discrepancy:" + f.name, composition);
    round.function.push_back(f.index);
  }
  const std::size_t n = round.candidates.size();
  round.results.resize(n);
  round.fits.resize(n);
  round.held_out.resize(n);
  round.refitted.assign(n, false);
  round.starts.resize(n);
  const std::vector<ParameterChoice> defaults = DefaultChoices(model);
  ParallelFor(static_cast<int>(n), options_.threads, [&](int c) {
    // The current fit's values and estimated set; of the discrepancy, only what it estimated and this
    // one, which the current fit (once it holds the discrepancy) has fixed at 0.
    std::vector<std::string> log;
    TermStart t = StartWithTerm(model, "discrepancy", current);
    std::vector<int> in = EstimatedFunctions(current);
    in.push_back(round.function[c]);
    const int position = model.defaults().position_of_index(round.function[c]);
    t.choices[position] = defaults[position];
    KeepOnlyFunctions(model, in, t);
    const CandidateStart start = DiscrepancyStartingValue(model, round.function[c], current, &log);
    for (const std::string& line : log) spdlog::debug("candidate {}: {}", round.candidates[c].first, line);
    for (const auto& [key, value] : start.values) t.start.set(key, value);
    t.size_score = start.size_score;
    round.starts[c] = std::move(t);
  });
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  const auto score = [&](std::size_t c) {
    const double t = round.starts[c]->size_score;
    return std::isfinite(t) ? std::abs(t) : -1.0;
  };
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return score(a) > score(b); });
  for (std::size_t k = static_cast<std::size_t>(options_.discrepancy_refits); k < n; ++k) {
    if (score(order[k]) >= 0.0) round.waiting.push_back(order[k]);
    CandidateFit& r = round.results[order[k]];
    r.term = round.candidates[order[k]].first;
    r.size_score = round.starts[order[k]]->size_score;
    r.screened = true;
    r.delta_bic = NAN;
    r.error = r.verdict = fmt::format("screened out: size score t {:+.2f}, not among the {} largest", r.size_score,
                                      options_.discrepancy_refits);
  }
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
    if (r.screened || round.refitted[c]) return;  // before the refits (EmpiricalCandidates), or done
    round.refitted[c] = true;
    r.term = candidates[c].first;
    try {
      const Model model = Model::Build(candidates[c].second, causality_);
      std::vector<std::string> log;
      TermStart start = round.starts[c] ? *round.starts[c] : StartWithTerm(model, r.term, current, &log);
      // A catalogue term beside the discrepancy: its functions stay as the current fit chose them.
      if (!round.starts[c] && model.has_term("discrepancy")) KeepOnlyFunctions(model, EstimatedFunctions(current), start);
      for (const std::string& line : log) spdlog::debug("candidate {}: {}", r.term, line);
      r.size_score = start.size_score;
      if (const std::optional<std::string> why = Screened(start, current)) {
        r.screened = true;
        r.delta_bic = NAN;
        r.error = r.verdict = *why;
        seconds[c] = watch.Seconds();
        return;
      }
      round.fits[c] = FitCandidate(r.term, model, std::move(start), current, round.function[c]);
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
// out of its fit better than the current model is kept. Returns its index, or -1. A candidate whose
// BIC change is not below `bic_below` (what `below_what` reaches) is not a choice.
int DiscoveryRun::Select(Round& round, const FitSummary& current, const Model& model,
                         const std::map<std::string, double>& ratio, int number, double bic_below,
                         std::string_view below_what) {
  std::vector<CandidateFit>& results = round.results;
  std::vector<std::size_t> order;
  for (std::size_t c = 0; c < results.size(); ++c) {
    CandidateFit& r = results[c];
    if (r.screened || r.verdict == kNotBetterHeldOut) {
      continue;  // its verdict says why (a candidate the held-out test refused in an earlier pass)
    } else if (!r.ok) {
      r.verdict = "no converged fit";
    } else if (r.delta_bic > -options_.bic_threshold) {
      r.verdict = fmt::format("BIC does not fall by {}", options_.bic_threshold);
    } else if (!(r.delta_bic < bic_below)) {
      r.verdict = fmt::format("BIC not {} below {}'s", options_.bic_threshold, below_what);
    } else if (MeanRatio(r.noise_ratio) - 1.0 > options_.min_improvement * (MeanRatio(ratio) - 1.0) ||
               !FallsBeyondNoise(current, round.fits[c])) {
      r.verdict = "noise ratio barely falls";
    } else {
      r.qualified = true;
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
    results[c].verdict = kNotBetterHeldOut;
  }
  return -1;
}

// The library against the term a catalogue round keeps (DiscoverOptions::challenge_terms): the
// functions that do not share its signature, refitted on the current fit. The empirical round and
// the function kept in the term's place, or nullopt when none explains the data better than the term
// by bic_threshold and predicts left-out experiments better than the current model.
std::optional<std::pair<Round, int>> DiscoveryRun::Challenge(const Round& round, int best, const FitSummary& current,
                                                             const Model& model,
                                                             const std::map<std::string, double>& ratio, int number) {
  const CandidateFit& kept = round.results[best];
  Round challengers = EmpiricalCandidates(current, kept.term);
  Say(fmt::format("round {}: the library against {}, {} functions of another signature refitted", number, kept.term,
                  std::min<std::size_t>(challengers.candidates.size(), options_.discrepancy_refits)));
  Refit(challengers, current, number);
  const int e = Select(challengers, current, model, ratio, number, kept.delta_bic - options_.bic_threshold, kept.term);
  LogCandidates(challengers);
  if (e < 0) return std::nullopt;
  return std::make_pair(std::move(challengers), e);
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
  if (round.function[best] > 0) {
    step.empirical = true;
    for (const DiscrepancyFunction& f : DiscrepancyLibrary())
      if (f.index == round.function[best]) step.evidence = "empirical, not a catalogue term: " + f.shape;
  } else {
    const TermEntry& entry = CatalogueEntry(step.term);
    step.evidence = entry.signature;
    for (const Finding& f : findings)
      if (f.locus == entry.locus) {
        step.evidence += "; " + f.detail;
        break;
      }
  }
  const FitSummary& chosen = round.fits[best];
  // What the step estimates that the current fit did not (a discrepancy function's coefficient is
  // in the current model already, at 0 and fixed, from the second function on).
  for (int i = 0; i < chosen.parameters.size(); ++i) {
    const auto p = current.parameters.find(chosen.parameters.spec(i).key());
    if (chosen.estimates[i].estimated && !(p && current.estimates[*p].estimated))
      step.parameters.emplace_back(chosen.parameters.spec(i).key(), chosen.parameters.value(i));
  }
  return step;
}

// One round: the candidates (catalogue terms, or the discrepancy's functions), their refits and the
// selection; the kept one becomes the current fit. Whether one was kept.
bool DiscoveryRun::Advance(int number, bool empirical, FitSummary& current, std::map<std::string, double>& ratio,
                           DiscoveryResult& result) {
  const std::vector<Finding> findings = LocateMismatch(current);
  const Model model = Model::Build(current.model, causality_);
  Round round = empirical ? EmpiricalCandidates(current) : Candidates(current);
  Say(fmt::format("round {}: {} {} refitted, {} at a time", number, round.candidates.size(),
                  empirical ? "empirical functions" : "candidates", options_.threads));
  Refit(round, current, number);
  if (!empirical)
    for (CandidateFit& c : round.results) {
      const TermEntry& entry = CatalogueEntry(c.term);
      for (const Finding& f : findings)
        if (f.locus == entry.locus) c.evidence = std::max(c.evidence, f.score);
    }
  int best = Select(round, current, model, ratio, number);
  // An empirical round whose refitted functions all fail goes on to the next largest size scores,
  // once: far from the floor the Gauss-Newton step ranks poorly (a real gas at 7 times the noise
  // ranked a volume curving with the stroke and a drift above its own shape).
  if (empirical && best < 0 && !round.waiting.empty()) {
    for (int k = 0; k < options_.discrepancy_refits && !round.waiting.empty(); ++k) {
      CandidateFit& r = round.results[round.waiting.front()];
      round.waiting.pop_front();
      r.screened = false;
      r.verdict.clear();
      r.error.clear();
    }
    Say(fmt::format("round {}: no function kept, the next {} size scores refitted", number, options_.discrepancy_refits));
    Refit(round, current, number);
    best = Select(round, current, model, ratio, number);
  }
  LogCandidates(round);
  // A term the library explains better is not named: the function takes its place, empirical.
  std::vector<CandidateFit> outdone;
  if (!empirical && best >= 0 && options_.discrepancy && options_.challenge_terms)
    if (auto challenge = Challenge(round, best, current, model, ratio, number)) {
      CandidateFit& term = round.results[best];
      const CandidateFit& function = challenge->first.results[challenge->second];
      term.verdict = fmt::format("not named: the empirical {} explains the data better (ΔBIC {:+.1f} against {:+.1f})",
                                 function.term, function.delta_bic, term.delta_bic);
      Say(fmt::format("{} is {}", term.term, term.verdict));
      outdone = round.results;
      round = std::move(challenge->first);
      best = challenge->second;
      empirical = true;
    }
  if (best < 0) {
    Say(empirical ? "no further function of the discrepancy improves the fit beyond what it costs and predicts "
                    "left-out experiments better"
                  : "no candidate improves the fit beyond what its parameters cost and predicts left-out experiments "
                    "better");
    return false;
  }
  round.results[best].verdict = "kept";
  DiscoveryStep step = Step(round, best, current, findings, ratio);
  step.candidates.insert(step.candidates.begin(), outdone.begin(), outdone.end());
  Say(fmt::format("added {}: ΔBIC {:+.1f}; {}", step.term, step.delta_bic, step.evidence));
  if (!empirical) {
    result.missing.push_back(step.term);
    KeptWithRivals kept{static_cast<int>(result.steps.size()), step.term, {}};
    for (std::size_t c = 0; c < round.results.size(); ++c)
      if (static_cast<int>(c) != best && round.results[c].qualified &&
          round.results[c].verdict != kNotBetterHeldOut)
        kept.rivals.emplace_back(round.results[c].term, std::move(round.fits[c]));
    if (!kept.rivals.empty()) kept_with_rivals_.push_back(std::move(kept));
  }
  result.steps.push_back(std::move(step));
  current = round.fits[best];
  current_cv_ = round.held_out[best];
  ratio = PooledNoiseRatio(current);
  return true;
}

// The keys of the parameters `with` has and `without` has not that size a term (ParameterSpec::sizes_term).
std::vector<std::string> SizeKeys(const Model& with, const Model& without) {
  std::vector<std::string> keys;
  for (int i = 0; i < with.defaults().size(); ++i) {
    const ParameterSpec& spec = with.defaults().spec(i);
    if (spec.sizes_term && !without.defaults().find(spec.key())) keys.push_back(spec.key());
  }
  return keys;
}

// The largest |correlation| of a fit's estimates between a parameter of `a` and one of `b` (NaN: none estimated).
double LargestCorrelation(const FitSummary& fit, const std::vector<std::string>& a, const std::vector<std::string>& b) {
  const auto column = [&](const std::string& key) -> int {
    const auto p = fit.parameters.find(key);
    if (!p) return -1;
    const auto it = std::find(fit.estimated_positions.begin(), fit.estimated_positions.end(), *p);
    return it == fit.estimated_positions.end() ? -1 : static_cast<int>(it - fit.estimated_positions.begin());
  };
  double largest = NAN;
  for (const std::string& ka : a)
    for (const std::string& kb : b) {
      const int i = column(ka), j = column(kb);
      if (i < 0 || j < 0 || i >= fit.correlation.rows() || j >= fit.correlation.cols()) continue;
      const double r = fit.correlation(i, j);
      if (std::isfinite(r) && !(std::abs(r) <= std::abs(largest))) largest = r;
    }
  return largest;
}

// The rival in the kept term's place (the final model's terms in order, the kept one swapped) and
// the two fitted together.
RivalExplanation DiscoveryRun::CompareRival(const KeptWithRivals& kept, const std::string& rival,
                                            const FitSummary& rival_fit, const DiscoveryResult& result) const {
  RivalExplanation out;
  out.term = rival;
  std::string swapped = base_;
  for (const std::string& term : result.missing) swapped += "+" + (term == kept.kept ? rival : term);
  const Model final_model = Model::Build(result.final_model, causality_);
  const bool later_steps = kept.step + 1 < static_cast<int>(result.steps.size());
  if (final_model.has_term("discrepancy")) swapped += "+discrepancy";
  const Model swap_model = Model::Build(swapped, causality_);
  out.model = swap_model.composition();
  // The rival's round fit is the swapped model when nothing was added after the kept term; else the
  // swapped model is fitted as identify fits a composition (FitPrepared: the data's start, then the
  // terms one at a time). An empirical discrepancy after it is discovery's own selection, which
  // FitPrepared would not repeat: that swap is left unfitted.
  if (!later_steps) {
    out.fit = rival_fit;
  } else if (!final_model.has_term("discrepancy")) {
    SessionFitOptions own = session_options_;
    own.composition = swapped;
    own.estimator.threads = 1;
    out.fit = FitPrepared(data_, swap_model, own).summary;
  }
  if (out.fit.converged && out.fit.IsSolutionUsable()) {
    out.delta_bic = out.fit.bic - result.final_fit.bic;
    out.noise_ratio = PooledNoiseRatio(out.fit);
    out.at_noise_floor = AtNoiseFloor(out.fit);
  }
  // Both terms at once, from the final fit with the rival started where the mismatch puts it.
  const Model joint = Model::Build(result.final_model + "+" + rival, causality_);
  TermStart start = StartWithTerm(joint, rival, result.final_fit);
  EstimatorOptions estimator = session_options_.estimator;
  estimator.threads = 1;
  const FitSummary both = Estimator(joint, estimator).Fit(data_.experiments, start.start, start.choices, data_.issues);
  if (both.converged && both.IsSolutionUsable())
    out.correlation = LargestCorrelation(both, SizeKeys(joint, swap_model), SizeKeys(joint, final_model));
  if (std::isfinite(out.delta_bic) && out.delta_bic < options_.ambiguity_bic_margin)
    out.why = fmt::format("its model's BIC is {:+.1f} from the final model's, within the margin of {:g}", out.delta_bic,
                          options_.ambiguity_bic_margin);
  else if (std::abs(out.correlation) > options_.ambiguity_correlation)
    out.why = fmt::format("fitted together, the sizes of {} and {} are correlated {:+.3f} (beyond {:g})", kept.kept, rival,
                          out.correlation, options_.ambiguity_correlation);
  spdlog::info("  rival of {}: {} ΔBIC {:+.1f} against the final model, sizes correlated {:+.3f} fitted together: {}",
               kept.kept, rival, out.delta_bic, out.correlation, out.why.empty() ? "not alike" : out.why);
  return out;
}

// Refits `model` from `start` (the current fit less `name`) and, where the data do not support
// `name` (its absence costs less than the BIC threshold and keeps the fit where the floor test had
// it), takes it out: the refit becomes the current fit and a removed step says why (`context`).
bool DiscoveryRun::TakeOutIfUnsupported(const std::string& name, bool empirical, const Model& model,
                                        const TermStart& start, const std::string& context, FitSummary& current,
                                        std::map<std::string, double>& ratio, DiscoveryResult& result) const {
  FitSummary fit;
  try {
    fit = Estimator(model, session_options_.estimator).Fit(data_.experiments, start.start, start.choices, data_.issues);
  } catch (const EstimationError& e) {
    spdlog::debug("without {}: {}", name, e.what());
  } catch (const PeriodicSolverError& e) {
    spdlog::debug("without {}: {}", name, e.what());
  }
  const double delta = fit.bic - current.bic;
  if (!fit.converged || !fit.IsSolutionUsable() || !(delta < options_.bic_threshold) ||
      (AtNoiseFloor(current) && !AtNoiseFloor(fit)))
    return false;
  DiscoveryStep step;
  step.term = name;
  step.empirical = empirical;
  step.removed = true;
  step.delta_bic = delta;
  step.noise_before = ratio;
  step.noise_after = PooledNoiseRatio(fit);
  step.evidence = fmt::format("taken out again: {}, the data do not support it (without it the BIC changes by {:+.1f}, "
                              "less than {:g})",
                              context, delta, options_.bic_threshold);
  Say(fmt::format("removed {}: {}", name, step.evidence));
  result.steps.push_back(std::move(step));
  current = std::move(fit);
  ratio = PooledNoiseRatio(current);
  return true;
}

// Backward elimination once the empirical discrepancy is in: a catalogue term added before it may
// have taken up part of what the discrepancy now models (a gas law bent to follow a charge that
// leaks). Each is refitted away, last added first, from the current values and estimated set.
void DiscoveryRun::RemoveUnsupportedTerms(FitSummary& current, std::map<std::string, double>& ratio,
                                          DiscoveryResult& result) const {
  for (auto term = result.missing.rbegin(); term != result.missing.rend();) {
    std::string without = base_;
    for (const std::string& t : result.missing)
      if (t != *term) without += "+" + t;
    without += "+discrepancy";
    std::optional<Model> model;
    try {
      model = Model::Build(without, causality_);
    } catch (const ModelError& e) {  // another term needs it
      spdlog::debug("without {}: {}", *term, e.what());
      ++term;
      continue;
    }
    TermStart start = StartFromFit(*model, current);
    // A function whose catalogue twin the term was joins the model with it gone; it stays at 0
    // like every function no round chose.
    KeepOnlyFunctions(*model, EstimatedFunctions(current), start);
    if (TakeOutIfUnsupported(*term, false, *model, start, "with the empirical discrepancy in", current, ratio, result))
      term = decltype(term)(result.missing.erase(std::next(term).base()));
    else
      ++term;
  }
  RemoveUnsupportedFunctions(current, ratio, result);
}

// The same for the discrepancy's own functions, the last chosen first: one chosen early may have
// stood in for what a later one models better (a gas drift for a heat flow), and stays in the sum
// at a size the data no longer support. The last function standing stays.
void DiscoveryRun::RemoveUnsupportedFunctions(FitSummary& current, std::map<std::string, double>& ratio,
                                              DiscoveryResult& result) const {
  std::vector<std::string> chosen;  // "discrepancy:NAME", in the order the rounds added them
  for (const DiscoveryStep& step : result.steps)
    if (step.empirical && !step.removed) chosen.push_back(step.term);
  const Model model = Model::Build(current.model, causality_);
  for (auto function = chosen.rbegin(); function != chosen.rend() && chosen.size() > 1;) {
    const auto entry = std::find_if(DiscrepancyLibrary().begin(), DiscrepancyLibrary().end(),
                                    [&](const DiscrepancyFunction& f) { return "discrepancy:" + f.name == *function; });
    bool out = false;
    if (entry != DiscrepancyLibrary().end() && model.defaults().position_of_index(entry->index) >= 0) {
      TermStart start = StartFromFit(model, current);
      std::vector<int> in = EstimatedFunctions(current);
      std::erase(in, entry->index);
      KeepOnlyFunctions(model, in, start);
      out = TakeOutIfUnsupported(*function, true, model, start, "with the functions chosen after it", current, ratio,
                                 result);
    }
    if (out)
      function = decltype(function)(chosen.erase(std::next(function).base()));
    else
      ++function;
  }
}

void DiscoveryRun::FindAmbiguities(DiscoveryResult& result) const {
  if (!options_.ambiguity || kept_with_rivals_.empty()) return;
  const Stopwatch watch;
  std::vector<std::pair<const KeptWithRivals*, const std::pair<std::string, FitSummary>*>> work;
  const Model final_model = Model::Build(result.final_model, causality_);
  for (const KeptWithRivals& kept : kept_with_rivals_) {
    // A term taken out again (RemoveUnsupportedTerms) has no place left to swap a rival into.
    if (std::find(result.missing.begin(), result.missing.end(), kept.kept) == result.missing.end()) continue;
    for (const auto& rival : kept.rivals)
      if (!final_model.has_term(rival.first)) work.emplace_back(&kept, &rival);
  }
  Say(fmt::format("comparing {} rival explanations with the final model", work.size()));
  std::vector<std::optional<RivalExplanation>> compared(work.size());
  ParallelFor(static_cast<int>(work.size()), options_.threads, [&](int k) {
    try {
      compared[k] = CompareRival(*work[k].first, work[k].second->first, work[k].second->second, result);
    } catch (const EstimationError& e) {  // a rival model without a fit is no rival
      spdlog::debug("rival {}: {}", work[k].second->first, e.what());
    } catch (const PeriodicSolverError& e) {
      spdlog::debug("rival {}: {}", work[k].second->first, e.what());
    } catch (const ModelError& e) {  // the two terms do not compose
      spdlog::debug("rival {}: {}", work[k].second->first, e.what());
    }
  });
  const TestSpace space = options_.test_space ? *options_.test_space : TestSpaceOf(data_.experiments);
  for (const KeptWithRivals& kept : kept_with_rivals_) {
    Ambiguity ambiguity{kept.kept, kept.step, {}, std::nullopt};
    for (std::size_t k = 0; k < work.size(); ++k)
      if (work[k].first == &kept && compared[k] && !compared[k]->why.empty()) ambiguity.rivals.push_back(*compared[k]);
    if (ambiguity.rivals.empty()) continue;
    std::sort(ambiguity.rivals.begin(), ambiguity.rivals.end(), [](const RivalExplanation& a, const RivalExplanation& b) {
      return (std::isfinite(a.delta_bic) ? a.delta_bic : INFINITY) < (std::isfinite(b.delta_bic) ? b.delta_bic : INFINITY);
    });
    const RivalExplanation& first = ambiguity.rivals.front();
    if (first.fit.converged && space.IsValid(nullptr)) ambiguity.test = ProposeDecisiveTest(result.final_fit, first.fit, space);
    result.ambiguities.push_back(std::move(ambiguity));
  }
  spdlog::debug("timing: rivals and decisive tests {:.2f} s", watch.Seconds());
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
  std::string empirical;
  if (result.discrepancy && !result.discrepancy->functions.empty()) {
    const EmpiricalDiscrepancy& d = *result.discrepancy;
    std::string names, dependence, resembles;
    for (const DiscrepancyTerm& f : d.functions) names += (names.empty() ? "" : ", ") + f.name;
    for (const std::string& line : d.dependence) dependence += (dependence.empty() ? "" : "; ") + line;
    for (const std::string& term : d.resembles) resembles += (resembles.empty() ? "" : ", ") + term;
    empirical = fmt::format(" What {} leaves is modelled empirically (an empirical discrepancy, not a catalogue term: {}): "
                            "{}.{}",
                            added.empty() ? "the catalogue" : "it", names, dependence,
                            resembles.empty() ? "" : " Its shape resembles the signature of " + resembles + ".");
  }
  std::string alike;
  for (const Ambiguity& a : result.ambiguities) {
    std::string rivals;
    for (const RivalExplanation& r : a.rivals)
      rivals += fmt::format("{}{} ({})", rivals.empty() ? "" : "; ", r.term, r.why);
    alike += fmt::format(" The data cannot tell {} from {}: {}.{}", a.kept,
                         a.rivals.size() == 1 ? a.rivals.front().term : "its rivals", rivals,
                         a.test ? " The test that decides: " + a.test->Describe() + "." : "");
  }
  result.conclusion = fmt::format(
      "{} left residuals above the noise floor (noise ratios{}). {}{} Final model {} (noise ratios{}{}).{}{}", base_, ratios,
      added.empty() ? "No catalogue term explains them." : "Missing: " + added + ".", empirical, result.final_model,
      after, at_floor ? ", at the noise floor" : ", still above the noise floor",
      result.unexplained.empty()
          ? ""
          : (exhausted ? " What is left matches no catalogue term: "
                       : fmt::format(" Stopped after {} terms; the strongest feature left: ", options_.max_terms)) +
                result.unexplained.front().detail + ".",
      alike);
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

  int number = 1;
  for (; number <= options_.max_terms && !AtNoiseFloor(current); ++number)
    if (!Advance(number, /*empirical=*/false, current, ratio, result)) {
      exhausted = true;
      break;
    }
  if (exhausted && options_.discrepancy && options_.max_discrepancy_functions > 0 && !AtNoiseFloor(current)) {
    Say("no catalogue term explains what is left: it is modelled empirically, the discrepancy's functions one at a time");
    for (int added = 0; added < options_.max_discrepancy_functions && !AtNoiseFloor(current); ++added, ++number)
      if (!Advance(number, /*empirical=*/true, current, ratio, result)) break;
  }
  if (Model::Build(current.model, causality_).has_term("discrepancy")) {
    RemoveUnsupportedTerms(current, ratio, result);
    result.discrepancy = DescribeDiscrepancy(current);
  }

  result.final_model = current.model;
  result.final_fit = current;
  FindAmbiguities(result);
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

const Ambiguity* DecidableAmbiguity(const DiscoveryResult& result) {
  const auto a = std::find_if(result.ambiguities.begin(), result.ambiguities.end(),
                              [](const Ambiguity& x) { return x.test.has_value(); });
  return a == result.ambiguities.end() ? nullptr : &*a;
}

Decision DecideAmbiguity(const DiscoveryResult& result, const FitData& with_test, const SessionFitOptions& fit,
                         const DiscoverOptions& options) {
  const Ambiguity* ambiguity = DecidableAmbiguity(result);
  if (!ambiguity) throw std::invalid_argument("decide: no two explanations fit alike, there is nothing to decide");
  std::vector<std::string> models{result.final_model};
  std::vector<const FitSummary*> starts{&result.final_fit};
  for (const RivalExplanation& r : ambiguity->rivals) {
    models.push_back(r.model);
    starts.push_back(r.fit.IsSolutionUsable() ? &r.fit : nullptr);
  }
  return Decide(with_test, models, fit, options.ambiguity_bic_margin, options.threads, starts);
}

DiscoveryResult Discover(const FitData& data, const SessionFitOptions& fit_options, const DiscoverOptions& options,
                         const std::function<void(const std::string&)>& progress) {
  std::string error;
  if (!options.IsValid(&error) || !fit_options.IsValid(&error)) throw std::invalid_argument("discover options: " + error);
  return DiscoveryRun(data, fit_options, options, progress).Run();
}

}  // namespace strut::ident
