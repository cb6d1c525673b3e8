#include "strut/study/confusion.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <nlohmann/json.hpp>
#include <map>
#include <random>
#include <stdexcept>

#include "strut/ident/discover.h"
#include "strut/rig/safety.h"
#include "strut/sim/simulated_rig.h"
#include "strut/study/statistics.h"

namespace strut::study {
namespace {

// The one effect a drawn base holds rather than adds: from 1dof+heat-exchange, the gas solubility.
constexpr const char* kBaseHeldEffect = "gas-solubility";

sim::Truth DrawConfusionUnit(const ConfusionOptions& options, const std::string& effect, const StudyRange* study,
                             unsigned long seed) {
  sim::Truth around = sim::WithIdealRig(sim::DefaultTruth());
  if (options.servo) around.actuator.ideal = false;
  if (options.shipped_calibration) around.sensors = sim::DefaultTruth().sensors;
  sim::UnitDraw draw;
  draw.base = options.base;
  if (effect == kBaseHeldEffect) {
    // 2dof is 1dof+heat-exchange with the gas solubility: the unit's base holds it, drawn as the
    // simulated rig draws it (0-2 times the nominal), and discovery starts from the base without it.
    draw.base = "2dof";
  } else if (effect != "none") {
    std::optional<double> size;
    if (study && !study->via_draw) {
      // Its own stream, so the size does not move the unit's other drawn quantities.
      std::mt19937_64 engine(seed * 7919 + 17);
      const double v = sim::UnitUniform(engine());
      size = study->log ? study->low * std::pow(study->high / study->low, v) : study->low + (study->high - study->low) * v;
    }
    draw.effects.push_back({effect, size});
  }
  return sim::DrawUnit(around, draw, seed);
}

// The first ambiguity's decisive test on the unit's rig (a noise seed of its own), and the
// decision with it: what `strut discover --decide` does over the drivers.
void Decide(const ident::DiscoveryResult& r, const sim::SimulatedRig& rig, const ident::FitData& data,
            const ident::SessionFitOptions& fit, const ident::DiscoverOptions& discover, unsigned long seed,
            ConfusionUnit& unit) {
  const ident::Ambiguity* ambiguity = ident::DecidableAmbiguity(r);
  if (!ambiguity) return;
  sim::RigRunOptions run;
  run.seed = seed + 1000003;
  ident::FitData with_test = data;
  const ident::FitData added = ident::PrepareFitData(rig.RunMatrix(rig::DecisiveTestPlan(*ambiguity->test), run), fmt::format("unit {} test", seed),
                                                     ident::Model::Build(fit.composition, fit.causality), fit.estimator.n);
  with_test.experiments.insert(with_test.experiments.end(), added.experiments.begin(), added.experiments.end());
  with_test.issues.insert(with_test.issues.end(), added.issues.begin(), added.issues.end());
  const ident::Decision d = ident::DecideAmbiguity(r, with_test, fit, discover);
  spdlog::info("unit {}: {}", seed, d.conclusion);
  unit.decided = d.winner >= 0 ? d.models[d.winner] : "";
  unit.decided_right = d.winner >= 0 && d.models[d.winner] == rig.model().composition();
}

// The function the discrepancy took first of those still in it at the end, and its coefficient's
// sign ("<0" or ">0").
std::pair<std::string, std::string> FirstFunction(const ident::DiscoveryResult& r) {
  if (!r.discrepancy) return {};
  constexpr std::string_view kPrefix = "discrepancy:";
  for (const ident::DiscoveryStep& step : r.steps) {
    if (!step.empirical || step.removed || !step.term.starts_with(kPrefix)) continue;
    const std::string name = step.term.substr(kPrefix.size());
    for (const ident::DiscrepancyTerm& f : r.discrepancy->functions)
      if (f.name == name) return {name, f.value < 0.0 ? "<0" : ">0"};
  }
  return {};
}

ConfusionUnit DiscoverUnit(const ConfusionOptions& options, const ident::SessionFitOptions& fit,
                           const ident::Model& model, const std::string& effect, const StudyRange* study,
                           unsigned long seed, daq::Session& session) {
  ConfusionUnit unit;
  unit.effect = effect;
  unit.seed = seed;
  const sim::Truth truth = DrawConfusionUnit(options, effect, study, seed);
  // How plainly the effect shows in this unit's data, before any fit absorbs part of it.
  if (effect != "none") unit.signal = sim::MeasureEffectSignal(truth, effect, rig::StandardMatrixPlan().experiments);
  const sim::SimulatedRig rig(truth);
  sim::RigRunOptions run;
  run.seed = seed;
  session = rig.RunMatrix(rig::StandardMatrixPlan(), run);
  const auto start = std::chrono::steady_clock::now();
  ident::DiscoverOptions discover;
  if (options.leave_out && effect != "none") discover.leave_out = {effect};
  const ident::FitData data = ident::PrepareFitData(session, fmt::format("unit {}", seed), model, fit.estimator.n);
  // As strut discover: the decisive test may go wherever the default limits allow.
  discover.test_space = rig::DecisiveTestSpace(data.experiments, rig::SafetyConfig{});
  const ident::DiscoveryResult r = ident::Discover(data, fit, discover);
  unit.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  unit.found = r.missing;
  unit.at_floor = r.final_fit.Verdict() == ident::FitVerdict::kAtNoiseFloor;
  if (r.discrepancy) {
    for (const ident::DiscrepancyTerm& f : r.discrepancy->functions) unit.empirical.push_back(f.name);
    unit.dependence = r.discrepancy->dependence;
  }
  const std::vector<std::string>& signature = SignatureFunctions(effect);
  const auto [first, sign] = FirstFunction(r);
  unit.described = !first.empty() && (std::find(signature.begin(), signature.end(), first) != signature.end() ||
                                      std::find(signature.begin(), signature.end(), first + sign) != signature.end());
  unit.right_first = effect != "none" && !r.missing.empty() && r.missing.front() == effect;
  unit.truth_named = unit.right_first;
  for (const ident::Ambiguity& a : r.ambiguities)
    for (const ident::RivalExplanation& rival : a.rivals) {
      unit.alike.push_back(a.kept + "~" + rival.term);
      if (a.step == 0 && a.kept == r.missing.front() && rival.term == effect) unit.truth_named = true;
    }
  if (options.decide) Decide(r, rig, data, fit, discover, seed, unit);
  if (study) {
    const ident::ParameterSet p = truth.Parameters(rig.model());
    unit.size = p.value(p.position_of_index(study->index));
  }
  if (!r.steps.empty())
    for (const ident::CandidateFit& c : r.steps.front().candidates)
      if (c.term == effect) unit.first_round = ConfusionUnit::FirstRound{c.delta_bic, c.cv_ratio, c.verdict};
  return unit;
}

}  // namespace

const std::vector<std::string>& SignatureFunctions(const std::string& term) {
  static const std::map<std::string, std::vector<std::string>> table = {
      {"recoil-damping", {"damping-direction", "damping-stroke-direction", "viscous-direction"}},
      {"metering-pin", {"damping-stroke", "damping-stroke-squared", "damping-stroke-direction"}},
      {"viscous-damping", {"viscous"}},
      {"friction-asymmetry", {"friction-direction"}},
      {"pressure-heat-transfer", {"conductance-pressure>0", "damping-pressure"}},
      {"stribeck-friction", {"friction-low-speed", "friction-low-speed-wide", "friction-low-speed-narrow"}},
      {"end-stop", {"contact-top-out", "contact-top-out-rate"}},
      {"charge-loss", {"gas-drift", "force-drift"}},
      {"gas-solubility", {"gas-pressure"}},
      {"dead-volume", {"volume-stroke-squared", "volume-stroke-cubed", "stiffness-squared", "stiffness-cubed", "gas-pressure"}},
      {"oil-compressibility", {"volume-pressure", "volume-stroke-squared", "volume-stroke-cubed", "stiffness-squared", "stiffness-cubed", "gas-pressure"}},
      {"real-gas", {"gas-pressure-temperature", "volume-pressure<0", "conductance-pressure<0", "volume-stroke-squared", "volume-stroke-cubed",
                    "stiffness-squared", "stiffness-cubed", "gas-pressure"}},
  };
  static const std::vector<std::string> none;
  const auto it = table.find(term);
  return it == table.end() ? none : it->second;
}

const std::vector<StudyRange>& StudyRanges() {
  static const std::vector<StudyRange> ranges = {
      {"viscous-damping", 18, 30.0, 3000.0, true, false, "N s/m"},
      {"stribeck-friction", 19, 0.02, 0.6, false, false, "-"},
      {"oil-compressibility", 26, 1e-10, 2e-9, true, false, "1/Pa"},
      {"real-gas", 31, 0.05, 1.5, false, false, "-"},
      {"end-stop", 23, 0.0, 8e-3, false, true, "m"},
      {"dead-volume", 36, 3e-4, 2e-2, true, false, "-"},
      {"charge-loss", 37, 2e-4, 3e-2, true, false, "-"},
      {"recoil-damping", 32, 0.02, 4.0, true, false, "-"},
      {"metering-pin", 33, 0.1, 8.0, true, false, "1/m"},
      {"friction-asymmetry", 34, 0.01, 0.4, true, false, "-"},
      {"pressure-heat-transfer", 35, 0.03, 1.0, true, false, "-"},
      // From 1dof+heat-exchange: the 2dof draw's own 0-2 times the nominal 2e-5 1/K.
      {"gas-solubility", 7, 0.0, 4e-5, false, true, "1/K"},
  };
  return ranges;
}

const StudyRange* FindStudyRange(const std::string& effect) {
  for (const StudyRange& r : StudyRanges())
    if (r.effect == effect) return &r;
  return nullptr;
}

double DetectionSize(std::vector<std::pair<double, bool>> units) {
  std::sort(units.begin(), units.end());
  for (std::size_t k = 0; k + 10 <= units.size(); ++k) {
    const long right = std::count_if(units.begin() + k, units.end(), [](const auto& u) { return u.second; });
    if (right >= 0.95 * static_cast<double>(units.size() - k)) return units[k].first;
  }
  return NAN;
}

std::vector<MeasureBin> Bins(std::vector<std::pair<double, bool>> units) {
  std::sort(units.begin(), units.end());
  std::vector<MeasureBin> bins;
  const std::size_t count = units.size();
  for (std::size_t b = 0; b < 5 && count > 0; ++b) {
    const std::size_t lo = b * count / 5, hi = (b + 1) * count / 5;
    if (hi <= lo) continue;
    const long k = std::count_if(units.begin() + lo, units.begin() + hi, [](const auto& x) { return x.second; });
    bins.push_back({units[lo].first, units[hi - 1].first, k, static_cast<long>(hi - lo)});
  }
  return bins;
}

ConfusionUnit RunConfusionUnit(const ConfusionOptions& options, const std::string& effect, int u,
                               daq::Session* session) {
  ident::SessionFitOptions fit;
  fit.composition = options.base;
  const ident::Model model = ident::Model::Build(options.base, fit.causality);
  daq::Session own;
  return DiscoverUnit(options, fit, model, effect, options.study_sizes ? FindStudyRange(effect) : nullptr,
                      options.first_seed + u, session ? *session : own);
}

ConfusionRow SummariseConfusion(const ConfusionOptions& options, const std::string& effect,
                                const std::vector<ConfusionUnit>& units) {
  ConfusionRow row;
  row.effect = effect;
  row.units = static_cast<int>(units.size());
  row.study = options.study_sizes ? FindStudyRange(effect) : nullptr;
  std::vector<double> seconds;
  std::vector<std::pair<double, bool>> by_size, by_signal, by_left;  // (measure, right first term)
  for (const ConfusionUnit& unit : units) {
    seconds.push_back(unit.seconds);
    if (unit.found.empty()) ++row.none;
    if (unit.right_first) ++row.right;
    const std::size_t expected = effect == "none" ? 0 : 1;
    if (unit.found.size() > expected || (effect != "none" && !unit.found.empty() && unit.found.front() != effect))
      ++row.extra;
    std::string names;
    for (const auto& t : unit.found) names += (names.empty() ? "" : "+") + t;
    ++row.added[names.empty() ? "(nothing)" : names];
    if (unit.signal) {
      by_signal.emplace_back(unit.signal->rms, unit.right_first);
      by_left.emplace_back(unit.signal->left_rms, unit.right_first);
    }
    if (unit.size) by_size.emplace_back(*unit.size, unit.right_first);
    row.at_floor += unit.at_floor;
    row.empirical += !unit.empirical.empty();
    row.described += unit.described;
    row.ambiguous += !unit.alike.empty();
    row.truth_named += unit.truth_named;
    row.tested += unit.decided.has_value();
    row.decided_right += unit.decided_right;
  }
  row.detection_signal = DetectionSize(by_signal);
  row.detection_left = DetectionSize(by_left);
  if (row.study) row.detection_size = DetectionSize(by_size);
  row.by_signal = Bins(by_signal);
  row.median_seconds = Median(seconds);
  return row;
}

void CheckConfusionEffects(const ConfusionOptions& options) {
  for (const std::string& effect : options.effects) {
    if (options.study_sizes && effect != "none" && !FindStudyRange(effect))
      throw std::invalid_argument(fmt::format("no study range for the effect '{}'", effect));
    if (effect == kBaseHeldEffect && options.base != "1dof+heat-exchange")
      throw std::invalid_argument(fmt::format("the effect '{}' is studied from the base 1dof+heat-exchange (the units "
                                              "are 2dof), not from {}",
                                              effect, options.base));
  }
}

std::vector<ConfusionRow> RunConfusionStudy(
    const ConfusionOptions& options, const std::function<void(const ConfusionUnit&, const daq::Session&)>& on_unit) {
  CheckConfusionEffects(options);
  std::vector<ConfusionRow> rows;
  for (const std::string& effect : options.effects) {
    std::vector<ConfusionUnit> units;
    for (int u = 0; u < options.units; ++u) {
      daq::Session session;
      units.push_back(RunConfusionUnit(options, effect, u, &session));
      if (on_unit) on_unit(units.back(), session);
    }
    rows.push_back(SummariseConfusion(options, effect, units));
  }
  return rows;
}

nlohmann::json ConfusionUnitJson(const ConfusionUnit& unit) {
  nlohmann::json row{{"effect", unit.effect}, {"seed", unit.seed}, {"found", unit.found},
                     {"right_first", unit.right_first}, {"seconds", unit.seconds}};
  if (const auto& s = unit.signal)
    row["signal"] = {{"rms", s->rms},           {"experiment", s->experiment},
                     {"channel", s->channel},   {"chi2", s->chi2},
                     {"left_rms", s->left_rms}, {"left_experiment", s->left_experiment},
                     {"left_channel", s->left_channel}};
  if (unit.size) row["size"] = *unit.size;
  row["empirical"] = unit.empirical;
  row["dependence"] = unit.dependence;
  row["at_floor"] = unit.at_floor;
  row["described"] = unit.described;
  row["alike"] = unit.alike;
  row["truth_named"] = unit.truth_named;
  if (unit.decided) {
    row["decided"] = *unit.decided;
    row["decided_right"] = unit.decided_right;
  }
  if (const auto& f = unit.first_round)
    row["first_round"] = {{"delta_bic", f->delta_bic}, {"cv_ratio", f->cv_ratio}, {"verdict", f->verdict}};
  return row;
}

ConfusionUnit ConfusionUnitFromJson(const nlohmann::json& j) {
  ConfusionUnit unit;
  unit.effect = j.at("effect").get<std::string>();
  unit.seed = j.at("seed").get<unsigned long>();
  unit.found = j.at("found").get<std::vector<std::string>>();
  unit.right_first = j.at("right_first").get<bool>();
  unit.seconds = j.at("seconds").get<double>();
  if (const auto s = j.find("signal"); s != j.end())
    unit.signal = sim::EffectSignal{s->at("rms").get<double>(),      s->at("experiment").get<std::string>(),
                                    s->at("channel").get<std::string>(), s->at("chi2").get<double>(),
                                    s->at("left_rms").get<double>(), s->at("left_experiment").get<std::string>(),
                                    s->at("left_channel").get<std::string>()};
  if (const auto s = j.find("size"); s != j.end()) unit.size = s->get<double>();
  // Shards written before the discrepancy lack these: read as nothing empirical, not at the floor.
  unit.empirical = j.value("empirical", std::vector<std::string>{});
  unit.dependence = j.value("dependence", std::vector<std::string>{});
  unit.at_floor = j.value("at_floor", false);
  unit.described = j.value("described", false);
  // Shards written before the ambiguity: nothing named alike, the truth named as it was first.
  unit.alike = j.value("alike", std::vector<std::string>{});
  unit.truth_named = j.value("truth_named", unit.right_first);
  if (const auto d = j.find("decided"); d != j.end()) {
    unit.decided = d->get<std::string>();
    unit.decided_right = j.value("decided_right", false);
  }
  if (const auto f = j.find("first_round"); f != j.end())
    unit.first_round = ConfusionUnit::FirstRound{f->at("delta_bic").get<double>(), f->at("cv_ratio").get<double>(),
                                                 f->at("verdict").get<std::string>()};
  return unit;
}

nlohmann::json ConfusionRowJson(const ConfusionRow& row) {
  nlohmann::json j{{"effect", row.effect},      {"units", row.units},
                   {"right_first", row.right},  {"extra", row.extra},
                   {"nothing_found", row.none}, {"median_seconds", row.median_seconds},
                   {"added", row.added},        {"at_floor", row.at_floor},
                   {"empirical", row.empirical}, {"described", row.described},
                   {"ambiguous", row.ambiguous}, {"truth_named", row.truth_named},
                   {"tested", row.tested},       {"decided_right", row.decided_right}};
  if (std::isfinite(row.detection_signal)) j["detection_signal"] = row.detection_signal;
  if (std::isfinite(row.detection_left)) j["detection_left"] = row.detection_left;
  if (std::isfinite(row.detection_size)) j["detection_size"] = row.detection_size;
  return j;
}

std::string ConfusionHeading(const ConfusionOptions& options) {
  return fmt::format("discovery from {} on drawn units ({} per row, seeds {}..), {} actuator, {} calibration{}:\n",
                     options.base, options.units, options.first_seed, options.servo ? "servo" : "ideal",
                     options.shipped_calibration ? "shipped" : "perfect",
                     options.leave_out ? ", each effect left out of the catalogue (leave-one-out)" : "") +
         (options.decide ? "  (ambiguous units: the decisive test run, decided right / tested)\n" : "") +
         fmt::format("  {:<20} {:>6} {:>12} {:>12} {:>10} {:>10} {:>9} {:>9} {:>9} {:>9} {:>11}  {}\n", "truth holds",
                     "units", "right first", "extra terms", "none found", "median s", "at floor", "empirical",
                     "described", "ambiguous", "truth named", "what was added");
}

std::string ConfusionRowLine(const ConfusionRow& row) {
  std::string what;
  for (const auto& [names, count] : row.added) what += fmt::format("{}{} x{}", what.empty() ? "" : ", ", names, count);
  return fmt::format("  {:<20} {:>6} {:>12} {:>12} {:>10} {:>10.2f} {:>9} {:>9} {:>9} {:>9} {:>11}  {}\n", row.effect,
                     row.units, row.effect == "none" ? std::string("-") : std::to_string(row.right), row.extra, row.none,
                     row.median_seconds, row.at_floor, row.empirical, row.described, row.ambiguous,
                     row.effect == "none" ? std::string("-") : std::to_string(row.truth_named),
                     what + (row.tested > 0 ? fmt::format("; decided right {}/{}", row.decided_right, row.tested) : ""));
}

std::string ConfusionDetection(const std::vector<ConfusionRow>& rows) {
  const auto shown = [](double x, std::string_view unit) {
    return std::isfinite(x) ? fmt::format("{:.3g} {}", x, unit) : std::string("not reached");
  };
  std::string lines;
  for (const ConfusionRow& row : rows) {
    if (row.effect == "none") continue;
    lines += fmt::format("  {}: detection (>= 95 % right first above it) in the signal {}, in the signal "
                         "left after the baseline {}",
                         row.effect, shown(row.detection_signal, "sd"), shown(row.detection_left, "sd"));
    if (const StudyRange* r = row.study)
      lines += fmt::format(", in theta{} ({} {:.3g}..{:.3g} {}) {}", r->index, r->log ? "log-uniform" : "uniform",
                           r->low, r->high, r->unit, shown(row.detection_size, r->unit));
    lines += "\n";
    for (const MeasureBin& b : row.by_signal)
      lines += fmt::format("    {:.3g}..{:.3g} {}: right first {}/{}\n", b.low, b.high, "sd", b.right, b.count);
  }
  if (lines.empty()) return lines;
  return "detection (signal: the effect's largest RMS over the noise sd in one experiment and channel; "
         "left: what the baseline's linearised refit leaves of it; units sorted by the signal in five bins):\n" +
         lines;
}

}  // namespace strut::study
