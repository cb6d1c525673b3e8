#include "strut/ident/discover.h"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <future>
#include <numeric>
#include <spdlog/spdlog.h>

#include "strut/ident/initial_values.h"
#include "terms.h"

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
      for (Eigen::Index i = 0; i < r.size(); ++i) n.rate[i] = stroke.At(e.phases[i], 1);
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

}  // namespace

bool DiscoverOptions::IsValid(std::string* error) const {
  if (!estimator.IsValid(error)) return false;
  const auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (!(bic_threshold >= 0)) return fail("bic_threshold must not be negative");
  if (!(noise_ratio_threshold > 1)) return fail("noise_ratio_threshold must be above 1");
  if (max_terms < 0 || threads < 1) return fail("max_terms must not be negative and threads at least 1");
  return true;
}

std::map<std::string, double> PooledNoiseRatio(const FitSummary& fit) {
  std::map<std::string, std::pair<double, long>> sums;
  for (const ExperimentFit& e : fit.experiments)
    for (const auto& [channel, r] : e.residual) {
      const double variance = e.noise_variance.count(channel) ? e.noise_variance.at(channel) : NAN;
      const bool fitted = std::any_of(e.channels.begin(), e.channels.end(),
                                      [&](const ChannelStatistics& c) { return c.channel == channel && c.fitted; });
      if (!(variance > 0) || !fitted) continue;
      sums[channel].first += r.squaredNorm() / variance;
      sums[channel].second += r.size();
    }
  std::map<std::string, double> ratio;
  for (const auto& [channel, s] : sums) ratio[channel] = s.second > 0 ? s.first / s.second : NAN;
  return ratio;
}

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
  }
  std::sort(findings.begin(), findings.end(), [](const Finding& a, const Finding& b) { return a.score > b.score; });
  return findings;
}

DiscoveryResult Discover(const std::vector<ExperimentData>& data, const std::string& base, Causality causality,
                         const DiscoverOptions& options, const std::vector<DataIssue>& issues,
                         const std::function<void(const std::string&)>& progress) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument("discover options: " + error);
  const auto say = [&](const std::string& text) {
    spdlog::info("{}", text);
    if (progress) progress(text);
  };
  // A fit of `composition`, starting from `previous` where parameters mean the same.
  const auto fit = [&](const std::string& composition, const FitSummary* previous) {
    const Model model = Model::Build(composition, causality);
    ParameterSet start = InitialValuesFromData(model, data, nullptr);
    std::vector<ParameterChoice> choices = DefaultChoices(model);
    for (int i = 0; i < start.size(); ++i) {
      const ParameterSpec& spec = start.spec(i);
      // Friction enters every experiment: a baseline with it pre-identified but fixed would show
      // friction residuals that no missing physics explains.
      if (spec.index >= 8 && spec.index <= 10 && model.has_term("pressure-friction")) choices[i].estimate = true;
      if (spec.sizes_term && !(previous && previous->parameters.find(spec.key()))) choices[i].estimate = true;
      if (!previous) continue;
      const auto p = previous->parameters.find(spec.key());
      if (p && previous->parameters.spec(*p).name == spec.name) {
        start.values()[i] = previous->parameters.value(*p);
        choices[i].estimate = previous->estimated[*p] || choices[i].estimate;
      }
    }
    return Estimator(model, options.estimator).Fit(data, start, choices, issues);
  };
  const auto worst_ratio = [](const std::map<std::string, double>& ratio) {
    double worst = 0.0;
    for (const auto& [c, r] : ratio) worst = std::max(worst, r);
    return worst;
  };

  const auto mean_ratio = [](const std::map<std::string, double>& ratio) {
    double sum = 0.0;
    for (const auto& [c, r] : ratio) sum += r;
    return ratio.empty() ? 0.0 : sum / ratio.size();
  };

  DiscoveryResult result;
  bool exhausted = false;  // stopped because no candidate qualified (not because of max_terms)
  say(fmt::format("fitting the baseline {}", base));
  result.baseline = fit(base, nullptr);
  result.mismatch = LocateMismatch(result.baseline);
  FitSummary current = result.baseline;
  std::map<std::string, double> ratio = PooledNoiseRatio(current);
  result.nothing_missing = worst_ratio(ratio) < options.noise_ratio_threshold;

  const auto& catalogue = Catalogue();
  for (int round = 0; round < options.max_terms && worst_ratio(ratio) >= options.noise_ratio_threshold; ++round) {
    const std::vector<Finding> findings = LocateMismatch(current);
    const Model model = Model::Build(current.model, causality);
    std::vector<std::pair<std::string, std::string>> candidates;  // term, composition
    for (const TermEntry& entry : catalogue) {
      if (entry.locus.empty() || model.has_term(entry.name)) continue;
      const std::string composition = current.model + "+" + entry.name;
      try {
        Model::Build(composition, causality);
        candidates.emplace_back(entry.name, composition);
      } catch (const ModelError& e) {
        spdlog::debug("candidate {} left out: {}", entry.name, e.what());
      }
    }
    say(fmt::format("round {}: {} candidates refitted, {} at a time", round + 1, candidates.size(), options.threads));
    std::vector<CandidateFit> results(candidates.size());
    std::vector<FitSummary> fits(candidates.size());
    for (std::size_t start = 0; start < candidates.size(); start += options.threads) {
      std::vector<std::future<void>> running;
      for (std::size_t c = start; c < std::min(candidates.size(), start + options.threads); ++c)
        running.push_back(std::async(std::launch::async, [&, c] {
          results[c].term = candidates[c].first;
          try {
            fits[c] = fit(candidates[c].second, &current);
            results[c].ok = fits[c].IsSolutionUsable();
            results[c].delta_bic = fits[c].bic - current.bic;
            results[c].noise_ratio = PooledNoiseRatio(fits[c]);
          } catch (const std::exception& e) {
            results[c].error = e.what();
          }
        }));
      for (auto& r : running) r.get();
    }
    for (CandidateFit& c : results) {
      const auto entry = std::find_if(catalogue.begin(), catalogue.end(), [&](const TermEntry& e) { return e.name == c.term; });
      for (const Finding& f : findings)
        if (f.locus == entry->locus) c.evidence = std::max(c.evidence, f.score);
    }
    // The best candidate by BIC that also brings the off channels down.
    int best = -1;
    for (std::size_t c = 0; c < results.size(); ++c) {
      if (!results[c].ok || results[c].delta_bic > -options.bic_threshold) continue;
      if (mean_ratio(results[c].noise_ratio) > options.min_improvement * mean_ratio(ratio)) continue;
      if (best < 0 || results[c].delta_bic < results[best].delta_bic) best = static_cast<int>(c);
    }
    for (const CandidateFit& c : results)
      spdlog::info("  {:<20} dBIC {:>12.1f}  worst noise ratio {:8.2f}  evidence {:6.1f}{}", c.term, c.delta_bic,
                   worst_ratio(c.noise_ratio), c.evidence, c.ok ? "" : "  (" + c.error + ")");
    if (best < 0) {
      say("no candidate improves the fit beyond what its parameters cost");
      exhausted = true;
      break;
    }
    DiscoveryStep step;
    step.term = results[best].term;
    step.delta_bic = results[best].delta_bic;
    step.noise_before = ratio;
    step.noise_after = results[best].noise_ratio;
    step.candidates = results;
    const auto entry = std::find_if(catalogue.begin(), catalogue.end(), [&](const TermEntry& e) { return e.name == step.term; });
    step.evidence = entry->signature;
    for (const Finding& f : findings)
      if (f.locus == entry->locus) {
        step.evidence += "; " + f.detail;
        break;
      }
    const FitSummary& chosen = fits[best];
    for (int i = 0; i < chosen.parameters.size(); ++i)
      if (chosen.parameters.spec(i).sizes_term && !current.parameters.find(chosen.parameters.spec(i).key()))
        step.parameters.emplace_back(chosen.parameters.spec(i).key(), chosen.parameters.value(i));
    say(fmt::format("added {}: BIC {:+.1f}; {}", step.term, step.delta_bic, step.evidence));
    result.missing.push_back(step.term);
    result.steps.push_back(std::move(step));
    current = chosen;
    ratio = PooledNoiseRatio(current);
  }

  result.final_model = current.model;
  result.final_fit = current;
  const double final_worst = worst_ratio(ratio);
  if (final_worst >= options.noise_ratio_threshold) {
    for (const Finding& f : LocateMismatch(current))
      if (f.score > 5.0) result.unexplained.push_back(f);
  }
  std::string ratios;
  for (const auto& [c, r] : PooledNoiseRatio(result.baseline)) ratios += fmt::format(" {} {:.2f}", c, r);
  if (result.nothing_missing) {
    result.conclusion = fmt::format("{} explains the data to the noise floor (noise ratios{}): nothing is missing.",
                                    base, ratios);
  } else {
    std::string added;
    for (const auto& t : result.missing) added += (added.empty() ? "" : ", ") + t;
    std::string after;
    for (const auto& [c, r] : ratio) after += fmt::format(" {} {:.2f}", c, r);
    result.conclusion = fmt::format(
        "{} left residuals above the noise floor (noise ratios{}). {} Final model {} (noise ratios{}).{}", base, ratios,
        added.empty() ? "No catalogue term explains them." : "Missing: " + added + ".", result.final_model, after,
        result.unexplained.empty()
            ? ""
            : (exhausted ? " What is left matches no catalogue term: "
                         : fmt::format(" Stopped after {} terms; the strongest feature left: ", options.max_terms)) +
                  result.unexplained.front().detail + ".");
  }
  say(result.conclusion);
  return result;
}

}  // namespace strut::ident
