#include "strut/ident/session_fit.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <optional>
#include <set>
#include <spdlog/spdlog.h>

#include "strut/daq/session.h"
#include "strut/ident/fit_problem.h"
#include "strut/ident/initial_values.h"
#include "strut/ident/term_start.h"

#include "strut/ident/assignments.h"
#include "strut/ident/catalogue.h"

namespace strut::ident {
namespace {

//! "c" or "c:force" split into experiment and channel (empty: the whole experiment).
std::pair<std::string, std::string> SplitExclusion(const std::string& item) {
  const std::size_t colon = item.rfind(':');
  if (colon == std::string::npos) return {item, ""};
  return {item.substr(0, colon), item.substr(colon + 1)};
}

}  // namespace

std::map<std::string, double> ParseGainSd(const std::string& text) {
  std::map<std::string, double> out;
  if (text == "none") return out;
  for (const Assignment& a : SplitAssignments(text, "calibration", "CHANNEL=SD (force=0.2%) or 'none'")) {
    std::string_view value = a.value;
    const bool percent = value.ends_with('%');
    if (percent) value.remove_suffix(1);
    // The item is trimmed already; a blank left is one between the number and its % ("0.2 %").
    const bool blank = !value.empty() && std::isspace(static_cast<unsigned char>(value.back()));
    const std::optional<double> sd = blank ? std::nullopt : ParseNumber(value);
    if (!sd || !(*sd >= 0))
      throw std::invalid_argument(
          fmt::format("calibration '{}': the gain sd must be a number >= 0 (0.002 or 0.2%)", a.item));
    out[std::string(a.name)] = percent ? *sd / 100.0 : *sd;
  }
  return out;
}

void CheckGainChannels(const std::map<std::string, double>& gain_sd, const Model& model) {
  const std::vector<std::string> channels = model.output_channels();
  for (const auto& [channel, sd] : gain_sd)
    if (std::find(channels.begin(), channels.end(), channel) == channels.end())
      throw std::invalid_argument(fmt::format("'{}' is not a channel of the model {} (its channels: {})", channel,
                                              model.composition(), fmt::join(channels, ", ")));
}

bool SessionFitOptions::IsValid(std::string* error) const {
  if (!estimator.IsValid(error)) return false;
  for (const std::string& item : exclude)
    if (SplitExclusion(item).first.empty()) {
      if (error) *error = fmt::format("exclusion '{}' names no experiment (use LABEL or LABEL:CHANNEL)", item);
      return false;
    }
  return true;
}

namespace {

//! Prepares one session's experiments into `fit`; `used` marks the exclusions that named something.
//! `recorded` of one more session folded into `into`: the inverse-variance mean of the records.
void AddZero(std::optional<SessionZero>& into, const std::optional<daq::MeasuredZero>& recorded,
             const std::string& source) {
  if (!recorded) return;
  if (!into) {
    into = SessionZero{*recorded, source};
    return;
  }
  const double w0 = 1.0 / (into->zero.sd * into->zero.sd), w1 = 1.0 / (recorded->sd * recorded->sd);
  into->zero = {(w0 * into->zero.value + w1 * recorded->value) / (w0 + w1), 1.0 / std::sqrt(w0 + w1)};
  into->source += " and " + source;
}

void AddSession(FitData& fit, const daq::Session& session, const std::string& path, const Model& model, int n,
                const std::vector<std::string>& exclude, std::vector<bool>& used) {
  const daq::RecordedZeros zeros = daq::ReadRecordedZeros(session);
  AddZero(fit.load_cell_zero, zeros.load_cell, path + " /calibration load_cell_zero");
  AddZero(fit.stroke_zero, zeros.stroke, path + " /calibration stroke_zero");
  // Whole experiments left out are not prepared at all: a defect there must not stop the rest.
  daq::Session kept = session;
  kept.experiments.clear();
  for (const daq::Experiment& e : session.experiments) {
    bool dropped = false;
    for (std::size_t k = 0; k < exclude.size(); ++k) {
      const auto [label, channel] = SplitExclusion(exclude[k]);
      if (label != e.label) continue;
      if (channel.empty()) {
        dropped = used[k] = true;
        fit.excluded.push_back(fmt::format("{}: experiment '{}' excluded by the user", path, e.label));
      } else if (std::any_of(e.channels.begin(), e.channels.end(), [&](const auto& c) { return c.name == channel; })) {
        used[k] = true;
      }
    }
    if (!dropped) kept.experiments.push_back(e);
  }
  std::vector<DataIssue> issues;
  auto prepared = PrepareExperiments(kept, model, n, &issues);
  for (auto& e : prepared) {
    const std::string original = e.label;
    const bool clash = std::any_of(fit.experiments.begin(), fit.experiments.end(),
                                   [&](const ExperimentData& d) { return d.label == e.label; });
    if (clash) e.label = path + ":" + e.label;  // several sessions may reuse labels
    for (DataIssue& issue : issues)
      if (issue.experiment == original) issue.experiment = e.label;
    // Channels left out by the user: recorded as issues, so the estimator does not fit them.
    for (const std::string& item : exclude) {
      const auto [label, channel] = SplitExclusion(item);
      if (label == original && !channel.empty() && e.channels.count(channel)) {
        issues.push_back({e.label, channel, "excluded", "left out by the user (--exclude)"});
        fit.excluded.push_back(
            fmt::format("{}: experiment '{}', channel '{}' excluded by the user", path, original, channel));
      }
    }
    fit.experiments.push_back(std::move(e));
  }
  for (TransientExperimentData& t : PrepareTransientExperiments(kept, path)) {
    const std::string original = t.label;
    const bool clash =
        std::any_of(fit.experiments.begin(), fit.experiments.end(), [&](const ExperimentData& d) { return d.label == t.label; }) ||
        std::any_of(fit.transients.begin(), fit.transients.end(),
                    [&](const TransientExperimentData& d) { return d.label == t.label; });
    if (clash) t.label = path + ":" + t.label;
    for (const std::string& item : exclude) {
      const auto [label, channel] = SplitExclusion(item);
      if (label == original && !channel.empty() && t.channels.count(channel)) {
        t.channels.erase(channel);
        fit.excluded.push_back(
            fmt::format("{}: experiment '{}', channel '{}' excluded by the user", path, original, channel));
      }
    }
    if (t.channels.empty()) {
      fit.excluded.push_back(fmt::format("{}: drop experiment '{}' has no channel left to fit", path, original));
      continue;
    }
    fit.transients.push_back(std::move(t));
  }
  fit.issues.insert(fit.issues.end(), issues.begin(), issues.end());
}

void CheckFitData(const FitData& fit, const std::vector<std::string>& exclude, const std::vector<bool>& used) {
  const std::string where = fit.sessions.size() == 1 ? fit.sessions[0] : "the sessions";
  for (std::size_t k = 0; k < exclude.size(); ++k)
    if (!used[k]) throw std::invalid_argument(fmt::format("--exclude {}: no such experiment or channel in {}", exclude[k], where));
  if (fit.experiments.empty()) throw std::invalid_argument(fmt::format("no complete periodic experiment in {}", where));
}

}  // namespace

FitData ReadFitData(const std::vector<std::string>& sessions, const Model& model, int n,
                    const std::vector<std::string>& exclude) {
  FitData fit;
  fit.sessions = sessions;
  std::vector<bool> used(exclude.size(), false);
  for (const std::string& path : sessions) AddSession(fit, daq::ReadSession(path), path, model, n, exclude, used);
  CheckFitData(fit, exclude, used);
  return fit;
}

FitData PrepareFitData(const daq::Session& session, const std::string& name, const Model& model, int n,
                       const std::vector<std::string>& exclude) {
  FitData fit;
  fit.sessions = {name};
  std::vector<bool> used(exclude.size(), false);
  AddSession(fit, session, name, model, n, exclude, used);
  CheckFitData(fit, exclude, used);
  return fit;
}

std::vector<std::string> FitPlan::Describe() const {
  std::vector<std::string> lines;
  for (int i = 0; i < start.size(); ++i) {
    const ParameterSpec& spec = start.spec(i);
    std::string how = choices[i].estimate ? "estimated" : "fixed";
    if (choices[i].estimate && choices[i].prior_sd)
      how += fmt::format(", prior sd {:.3g} {}", *choices[i].prior_sd, spec.unit);
    lines.push_back(fmt::format("{:<8} {:<28} = {:<12.6g} {:<10} {:<9} ({})", spec.key(), spec.name, start.value(i),
                                spec.unit, how, sources[i]));
  }
  for (const std::string& u : undetermined) lines.push_back("fixed, the data do not determine it: " + u);
  return lines;
}

FitPlan PlanFit(const Model& model, const FitData& data, const SessionFitOptions& options) {
  FitPlan plan;
  plan.start = InitialValuesFromData(model, data.experiments, nullptr, &plan.sources);
  // A zero the lab measured is data too: the mean of its parameter's prior.
  const std::pair<const std::optional<SessionZero>*, int> zeros[] = {{&data.load_cell_zero, kLoadCellZeroIndex},
                                                                     {&data.stroke_zero, kStrokeZeroIndex}};
  for (const auto& [zero, index] : zeros) {
    const int i = plan.start.position_of_index(index);
    if (!*zero || i < 0) continue;
    plan.start.values()[i] = (*zero)->zero.value;
    plan.sources[i] = fmt::format("recorded zero: {}, sd {:.3g} {}", (*zero)->source, (*zero)->zero.sd,
                                  plan.start.spec(i).unit);
  }
  plan.data_start = plan.start;
  plan.data_sources = plan.sources;
  // The user's values win over the data's: the file, then the assignments.
  std::vector<ParameterFileEntry> file;
  if (!options.params_file.empty()) {
    file = ReadParameterFile(options.params_file);
    plan.start.apply_file(options.params_file);  // checks every value against its physical range
    for (const ParameterFileEntry& entry : file)
      plan.sources[plan.start.position(entry.name)] = fmt::format("{} line {}", options.params_file, entry.line);
  }
  if (!options.assignments.empty()) {
    const ParameterSet before = plan.start;
    plan.start.apply_assignments(options.assignments);
    for (int i = 0; i < plan.start.size(); ++i)
      if (plan.start.value(i) != before.value(i) || options.assignments.find(plan.start.spec(i).key() + "=") != std::string::npos)
        plan.sources[i] = "--set";
  }
  plan.choices = ChoicesFromList(plan.start, options.estimate);
  for (const auto& [zero, index] : zeros) {
    const int i = plan.start.position_of_index(index);
    if (*zero && i >= 0 && plan.choices[i].estimate) plan.choices[i].prior_sd = (*zero)->zero.sd;
  }
  const bool defaults = options.estimate.empty() || options.estimate == "default";
  for (const ParameterFileEntry& entry : file) {
    const int i = plan.start.position(entry.name);
    if (entry.estimate && defaults) plan.choices[i] = ParameterChoice{*entry.estimate, plan.choices[i].prior_sd};
    if (entry.prior_sd) plan.choices[i].prior_sd = entry.prior_sd;
  }
  if (!defaults) return plan;

  // What the data can determine, judged at the data's own starting values (the user's values only
  // for the parameters that are not estimated), so what is estimated depends on the data and on
  // what the user says (the values given with --set or in a file: an end stop's known position),
  // not on the data's rough starting values.
  ParameterSet at = plan.data_start;
  for (int i = 0; i < at.size(); ++i)
    if (!plan.choices[i].estimate || plan.choices[i].prior_sd || plan.sources[i] != plan.data_sources[i])
      at.values()[i] = plan.start.value(i);
  for (Undetermined& u : UndeterminedAt(model, data, options.estimator, at, plan.choices, "the start")) {
    plan.choices[u.index].estimate = false;
    plan.undetermined_index.push_back(u.index);
    plan.undetermined.push_back(std::move(u.why));
  }
  return plan;
}

std::vector<Undetermined> UndeterminedAt(const Model& model, const FitData& data, const EstimatorOptions& estimator,
                                         const ParameterSet& at, const std::vector<ParameterChoice>& choices,
                                         std::string_view where) {
  // With the channels' noise floors as their variances, the sd each estimated parameter would have
  // at `at`. One that exceeds its size is fixed and named, the least determined first (fixing it can
  // make the others determinable).
  std::vector<Undetermined> fixed;
  std::vector<int> est;
  std::vector<double> scale(at.size());
  for (int i = 0; i < at.size(); ++i) {
    scale[i] = std::max({std::abs(at.value(i)), at.spec(i).typical_size(), 1e-300});
    if (choices[i].estimate) est.push_back(i);
  }
  if (est.empty()) return fixed;
  FitProblem problem(model, estimator, data.experiments, data.issues, est, scale, data.transients);
  problem.Solve(at.values(), true);
  if (problem.active_count() == 0) return fixed;  // the fit itself will say why
  std::vector<double> variance;
  for (const std::string& channel : problem.channels()) {
    double sum = 0.0;
    int count = 0;
    for (const ExperimentData& e : data.experiments) {
      const auto it = e.channels.find(channel);
      if (it != e.channels.end() && it->second.mean_noise_variance > 0) sum += it->second.mean_noise_variance, ++count;
    }
    for (const TransientExperimentData& t : data.transients)
      for (const auto& [name, recorded] : t.channels)
        if (TransientChannelName(t.kind, name) == channel && recorded.noise_variance > 0)
          sum += recorded.noise_variance, ++count;
    variance.push_back(count > 0 ? sum / count : 1.0);
  }
  const NormalEquations eq = problem.Linearise(at.values(), variance, {true, false, false, false});
  std::vector<int> kept(est.size());
  for (std::size_t k = 0; k < est.size(); ++k) kept[k] = static_cast<int>(k);
  while (!kept.empty()) {
    const Eigen::Index m = static_cast<Eigen::Index>(kept.size());
    Eigen::MatrixXd h(m, m);
    for (Eigen::Index a = 0; a < m; ++a) {
      for (Eigen::Index b = 0; b < m; ++b) h(a, b) = eq.information(kept[a], kept[b]);
      const auto& prior = choices[est[kept[a]]].prior_sd;
      if (prior) h(a, a) += std::pow(scale[est[kept[a]]] / *prior, 2);
    }
    // A ridge far below any determined parameter's information: a direction the data do not see at
    // all (a term whose effect no experiment reaches has exactly zero sensitivity) gets a huge sd
    // instead of the pseudo-inverse's zero.
    const double largest = std::max(h.diagonal().maxCoeff(), 1e-300);
    const double ridge = 1e-14 * largest;
    h.diagonal().array() += ridge;
    const Eigen::VectorXd sd = h.ldlt().solve(Eigen::MatrixXd::Identity(m, m)).diagonal().cwiseMax(0.0).cwiseSqrt();
    // In scaled units the typical size is 1 (or the start's size when that is larger).
    Eigen::Index worst = -1;
    double worst_ratio = 1.0;
    for (Eigen::Index a = 0; a < m; ++a) {
      const int i = est[kept[a]];
      // Against the parameter's own size where that is larger than its typical one (a sharpness
      // started at 5e4 s/m is determined to 10 % even when that is 2.5 of the typical 2e3).
      const double typical = std::max(at.spec(i).typical_size(), std::abs(at.value(i))) / scale[i];
      // No information at all (the data do not depend on it): undetermined whatever its size.
      const bool blind = !(h(a, a) - ridge > 1e-13 * largest);
      const double ratio = blind || !std::isfinite(sd[a]) ? INFINITY : sd[a] / std::max(typical, 1e-300);
      if (choices[i].prior_sd || !(ratio > worst_ratio)) continue;
      worst_ratio = ratio;
      worst = a;
    }
    if (worst < 0) break;
    const int i = est[kept[worst]];
    const double size = std::max(at.spec(i).typical_size(), std::abs(at.value(i)));
    const ParameterSpec& spec = at.spec(i);
    fixed.push_back(
        {i, std::isfinite(worst_ratio)
            ? fmt::format("{} {} (sd at {} {:.3g} {}, {:.3g} times its size {:.3g})", spec.key(), spec.name, where,
                          worst_ratio * size, spec.unit, worst_ratio, size)
            : fmt::format("{} {} (no experiment's outputs depend on it at {})", spec.key(), spec.name, where)});
    kept.erase(kept.begin() + worst);
  }
  return fixed;
}

TermStart StartFromFit(const Model& model, const FitSummary& previous) {
  TermStart t{model.defaults(), DefaultChoices(model)};
  for (int i = 0; i < t.start.size(); ++i) {
    const ParameterSpec& spec = t.start.spec(i);
    const auto p = previous.parameters.find(spec.key());
    if (p && previous.parameters.spec(*p).name == spec.name) {
      t.start.values()[i] = previous.parameters.value(*p);
      // What the previous fit estimated keeps its prior (a recorded zero's, not only the spec's).
      t.choices[i] = previous.estimates[*p].estimated ? ParameterChoice{true, previous.estimates[*p].prior_sd}
                                                      : ParameterChoice{};
    }
  }
  return t;
}

TermStart StartWithTerm(const Model& model, const std::string& term, const FitSummary& previous,
                        std::vector<std::string>* log) {
  TermStart t = StartFromFit(model, previous);
  if (model.causality() == Causality::kStrokeInput) {
    const CandidateStart candidate = CandidateStartingValues(term, previous, log);
    for (const auto& [key, value] : candidate.values) t.start.set(key, value);
    t.size_score = candidate.size_score;
  }
  return t;
}

namespace {

double Objective(const FitSummary& s) {
  return s.IsSolutionUsable() && !s.history.empty() ? s.history.back().objective : -INFINITY;
}

// Whether `other` is the better of two fits of the same model: converged where the first is not,
// else the higher log-posterior.
bool Better(const FitSummary& other, const FitSummary& than) {
  return (other.converged && !than.converged) || (other.converged == than.converged && Objective(other) > Objective(than));
}

// The composition's fit by continuation (FitPrepared): its base from the data, then its terms one
// at a time. nullopt when the composition is a base, or a step has no usable fit.
std::optional<FitSummary> FitByContinuation(const FitData& data, const Model& model, const FitPlan& plan,
                                            const SessionFitOptions& options,
                                            const std::function<void(const FitProgress&)>& progress) {
  // The canonical composition is its base and then the terms beyond it, in catalogue order.
  const std::string base = model.composition().substr(0, model.composition().find('+'));
  const std::vector<std::string>& base_terms = BaseTerms(base);
  std::vector<std::string> added;
  for (const std::string& term : model.term_names())
    if (std::find(base_terms.begin(), base_terms.end(), term) == base_terms.end()) added.push_back(term);
  if (added.empty()) return std::nullopt;
  SessionFitOptions base_options = options;
  base_options.composition = base;
  base_options.params_file.clear();  // the user's values are for the whole composition: kept below
  base_options.assignments.clear();
  try {
    FitSummary current = FitPrepared(data, Model::Build(base, model.causality()), base_options).summary;
    std::string composition = base;
    for (std::size_t k = 0; k < added.size(); ++k) {
      if (!current.IsSolutionUsable()) return std::nullopt;
      const bool last = k + 1 == added.size();
      composition += "+" + added[k];
      const Model step = last ? model : Model::Build(composition, model.causality());
      std::vector<std::string> log;
      TermStart t = StartWithTerm(step, added[k], current, &log);
      for (const std::string& line : log) spdlog::debug("continuation {}: {}", added[k], line);
      for (int i = 0; i < t.start.size(); ++i) {
        const auto p = plan.start.find(t.start.spec(i).key());
        if (p && plan.sources[*p] != plan.data_sources[*p]) t.start.values()[i] = plan.start.value(*p);
      }
      if (last) t.choices = plan.choices;
      current = Estimator(step, options.estimator)
                    .Fit(data.experiments, t.start, t.choices, data.issues, progress, data.transients);
      spdlog::debug("continuation: {} {} after {} iterations", composition, ToString(current.Verdict()),
                    current.iterations);
    }
    return current;
  } catch (const EstimationError& e) {
    spdlog::debug("continuation of {}: {}", model.composition(), e.what());
  } catch (const PeriodicSolverError& e) {
    spdlog::debug("continuation of {}: {}", model.composition(), e.what());
  } catch (const ModelError& e) {  // a step's composition is not a model (a term before what it needs)
    spdlog::debug("continuation of {}: {}", model.composition(), e.what());
  }
  return std::nullopt;
}

// What the data determine is judged at the start; a fit can move into reach of what was out of it.
// An end stop no experiment reaches at the data's start has its position fixed; the fit then bends
// the stroke zero theta12 until the fixed stop touches the top-out the data show, and ends at the
// noise floor with theta12 millimetres off and an sd of microns. So the fixed parameters are judged
// again at the fit, and where some are determined there, the fit goes on from it with them estimated.
void RejudgeUndetermined(SessionFit& fit, const Estimator& estimator, const SessionFitOptions& options,
                         const std::function<void(const FitProgress&)>& progress) {
  if (fit.plan.undetermined_index.empty() || !fit.summary.IsSolutionUsable()) return;
  std::vector<ParameterChoice> choices = fit.plan.choices;
  for (const int i : fit.plan.undetermined_index) choices[i].estimate = true;
  const std::vector<Undetermined> still =
      UndeterminedAt(fit.model, fit.data, options.estimator, fit.summary.parameters, choices, "the fit");
  // Only what was fixed at the start is in question here: the rest keeps the plan's choice.
  const auto stays_fixed = [&](int i) {
    return std::any_of(still.begin(), still.end(), [&](const Undetermined& u) { return u.index == i; });
  };
  std::string freed;
  std::vector<std::string> undetermined;
  std::vector<int> undetermined_index;
  for (std::size_t k = 0; k < fit.plan.undetermined_index.size(); ++k) {
    const int i = fit.plan.undetermined_index[k];
    if (stays_fixed(i)) {
      choices[i].estimate = false;
      undetermined.push_back(fit.plan.undetermined[k]);
      undetermined_index.push_back(i);
    } else {
      freed += (freed.empty() ? "" : ", ") + fit.plan.start.spec(i).key();
    }
  }
  if (freed.empty()) return;
  FitSummary again = estimator.Fit(fit.data.experiments, fit.summary.parameters, choices, fit.data.issues, progress,
                                   fit.data.transients);
  const bool better = Better(again, fit.summary);
  spdlog::info("{} determined at the fit, not at the start: the fit with {} estimated {}{}", freed,
               freed.find(',') == std::string::npos ? "it" : "them", ToString(again.Verdict()),
               better ? " (kept)" : "");
  if (!better) return;
  again.warnings.push_back(fmt::format("{} fixed at the start, where the data did not determine {}, and estimated from "
                                       "the fit on, where they do",
                                       freed, freed.find(',') == std::string::npos ? "it" : "them"));
  fit.summary = std::move(again);
  fit.plan.choices = std::move(choices);
  fit.plan.undetermined = std::move(undetermined);
  fit.plan.undetermined_index = std::move(undetermined_index);
}

}  // namespace

SessionFit FitPrepared(FitData data, const Model& model, const SessionFitOptions& options,
                       const std::function<void(const FitProgress&)>& progress) {
  FitPlan plan = PlanFit(model, data, options);
  return FitPlanned(std::move(data), model, std::move(plan), options, progress);
}

SessionFit FitPlanned(FitData data, const Model& model, FitPlan plan, const SessionFitOptions& options,
                      const std::function<void(const FitProgress&)>& progress) {
  SessionFit fit{model, std::move(data), std::move(plan), {}};
  const Estimator estimator(fit.model, options.estimator);
  fit.summary = estimator.Fit(fit.data.experiments, fit.plan.start, fit.plan.choices, fit.data.issues, progress,
                              fit.data.transients);
  if (fit.summary.Verdict() != FitVerdict::kAtNoiseFloor && fit.plan.data_start.values() != fit.plan.start.values()) {
    // A second start: the data's own values (what a fit of an unknown unit starts from).
    ParameterSet second = fit.plan.data_start;
    for (int i = 0; i < second.size(); ++i)
      if (fit.plan.choices[i].prior_sd || !fit.plan.choices[i].estimate) second.values()[i] = fit.plan.start.value(i);
    FitSummary other =
        estimator.Fit(fit.data.experiments, second, fit.plan.choices, fit.data.issues, progress, fit.data.transients);
    const bool better = Better(other, fit.summary);
    spdlog::info("the fit from the given starting values {}; from the data's own: {}{}",
                 ToString(fit.summary.Verdict()), ToString(other.Verdict()), better ? " (kept)" : "");
    if (better) {
      other.warnings.push_back(fmt::format(
          "the fit from the given starting values ended {} (log-posterior {:.6g}); this one, from the data's own "
          "starting values, reached {:.6g}",
          ToString(fit.summary.Verdict()), Objective(fit.summary), Objective(other)));
      fit.summary = std::move(other);
    }
  }
  const bool default_choices = options.estimate.empty() || options.estimate == "default";
  if (fit.summary.Verdict() != FitVerdict::kAtNoiseFloor && default_choices &&
      fit.model.causality() == Causality::kStrokeInput) {
    if (std::optional<FitSummary> continued = FitByContinuation(fit.data, fit.model, fit.plan, options, progress)) {
      const bool better = Better(*continued, fit.summary);
      spdlog::info("the fit from the data's start {}; by continuation from the base, one term at a time: {}{}",
                   ToString(fit.summary.Verdict()), ToString(continued->Verdict()), better ? " (kept)" : "");
      if (better) {
        continued->warnings.push_back(fmt::format(
            "the fit from the data's starting values ended {} (log-posterior {:.6g}); this one, reached by "
            "continuation (the base first, then each term from where the located mismatch puts it), {:.6g}",
            ToString(fit.summary.Verdict()), Objective(fit.summary), Objective(*continued)));
        fit.summary = std::move(*continued);
      }
    }
  }
  if (default_choices) RejudgeUndetermined(fit, estimator, options, progress);
  for (const std::string& u : fit.plan.undetermined)
    fit.summary.warnings.push_back("fixed at its starting value, the data do not determine it: " + u);
  return fit;
}

SessionFit FitSessions(const std::vector<std::string>& sessions, const SessionFitOptions& options,
                       const std::function<void(const FitProgress&)>& progress) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument(error);
  const Model model = Model::Build(options.composition, options.causality);
  const int n = FitGridPoints(options.estimator.n, options.estimator.scheme, model.causality());
  return FitPrepared(ReadFitData(sessions, model, n, options.exclude), model, options, progress);
}

}  // namespace strut::ident
