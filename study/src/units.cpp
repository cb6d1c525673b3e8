#include "strut/study/units.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <nlohmann/json.hpp>
#include <filesystem>
#include <random>

#include <unistd.h>

#include "strut/ident/session_fit.h"
#include "strut/sim/draw.h"
#include "strut/sim/simulated_rig.h"
#include "strut/study/cpu_time.h"
#include "strut/study/stroke_zero.h"

namespace strut::study {

sim::Truth DrawnUnitTruth(const UnitsOptions& options, unsigned long seed) {
  // The method's own figures: the actuator and the transducers' calibration of the shipped rig
  // are outside the damper model (docs/identification.md, "Units nobody has characterised");
  // servo and shipped_calibration put them back.
  sim::Truth around = sim::WithIdealRig(sim::DefaultTruth());
  if (options.servo) around.actuator.ideal = false;
  if (options.shipped_calibration) around.sensors = sim::DefaultTruth().sensors;
  sim::UnitDraw draw;
  draw.base = options.base;
  for (const std::string& e : options.effects) draw.effects.push_back({e, std::nullopt});
  if (options.effects_per_unit > 0) {
    // Which effects, from a stream of their own: the unit's drawn quantities stay those of its seed.
    std::vector<std::string> pool;
    for (const std::string& e : sim::ExtraEffects()) {
      if (std::find(options.effects.begin(), options.effects.end(), e) != options.effects.end()) continue;
      try {
        ident::Model::Build(options.base + "+" + e, ident::Causality::kStrokeInput);
        pool.push_back(e);
      } catch (const ident::ModelError&) {  // needs what the base lacks (pressure-heat-transfer on 1dof)
      }
    }
    std::mt19937_64 stream(seed * 104729 + 3);
    const int count = std::min<int>(static_cast<int>(pool.size()),
                                    1 + static_cast<int>(sim::UnitUniform(stream()) * options.effects_per_unit));
    std::shuffle(pool.begin(), pool.end(), stream);
    pool.resize(count);
    for (const std::string& e : sim::ExtraEffects())
      if (std::find(pool.begin(), pool.end(), e) != pool.end()) draw.effects.push_back({e, std::nullopt});
  }
  sim::Truth truth = sim::DrawUnit(around, draw, seed);
  if (options.drawn_gains) {
    // Transducers off by what the fit's default calibration says they may be (kLabGainSd): the
    // intervals, which hold that calibration, must still cover the truth at their rate.
    std::mt19937_64 stream(seed * 7919 + 17);
    std::normal_distribution<double> normal;
    truth.sensors.force.gain_error = ident::kLabGainSd.at("force") * normal(stream);
    truth.sensors.pressure.gain_error = ident::kLabGainSd.at("pressure") * normal(stream);
    truth.sensors.stroke.gain_error = ident::kLabGainSd.at("stroke") * normal(stream);
  }
  return truth;
}

namespace {

//! From a start up to `start_off` off in every estimated parameter, the same optimum within a
//! tenth of an sd. A parameter with a prior (the stroke zero) keeps its value: the prior's mean
//! is part of the problem, not of the start.
void Restart(const ident::SessionFit& fit, const ident::Model& model, const ident::SessionFitOptions& options,
             const ident::ParameterSet& truth, double start_off, UnitFit& unit) {
  const ident::FitSummary& s = fit.summary;
  std::mt19937_64 rng(unit.seed);
  std::uniform_real_distribution<double> off(-start_off, start_off);
  // The same estimated set (the plan), another start: through the entry point's fit, so a start
  // that ends off the floor is repeated from the data's own values as for any user.
  ident::FitPlan far = fit.plan;
  for (int i : s.estimated_positions) {
    const auto t = truth.find(far.start.spec(i).key());
    const double v = t ? truth.value(*t) : far.start.value(i);
    const double factor = 1.0 + off(rng);
    if (!far.choices[i].prior_sd) far.start.values()[i] = v * factor;
  }
  const ident::FitSummary again = ident::FitPlanned(fit.data, model, std::move(far), options).summary;
  double apart = 0.0;
  for (int i : s.estimated_positions)
    apart = std::max(apart, std::abs(again.parameters.value(i) - s.parameters.value(i)) / s.estimates[i].sd);
  unit.restarted = true;
  unit.restart_apart_sd = apart;
  unit.restart_converged = again.converged;
  unit.restart_iterations = again.iterations;
  unit.restart_warning = again.warnings.empty() ? "" : again.warnings.front();
  unit.same_optimum = again.converged && apart < 0.1;
}

UnitFit FitUnit(const UnitsOptions& options, const ident::SessionFitOptions& base_options,
                const ident::EstimatorOptions& uncalibrated, const ident::Model& base_model, int u) {
  UnitFit unit;
  unit.seed = options.first_seed + u;
  const sim::Truth truth = DrawnUnitTruth(options, unit.seed);
  const sim::SimulatedRig rig(truth);
  unit.truth_composition = rig.model().composition();
  ident::SessionFitOptions fit_options = base_options;
  if (options.fit_truth) fit_options.composition = unit.truth_composition;
  const ident::Model model =
      options.fit_truth ? ident::Model::Build(unit.truth_composition, fit_options.causality) : base_model;
  sim::RigRunOptions run;
  run.seed = unit.seed;
  daq::Session session = rig.RunMatrix(rig::StandardMatrixPlan(), run);
  if (options.top_out) {
    const std::string scratch = (std::filesystem::temp_directory_path() /
                                 fmt::format("strut-units-top-out-{}-{}.h5", ::getpid(), unit.seed))
                                    .string();
    const rig::RunReport reference = RunTopOutReference(truth, rig::TopOutOptions{}, 100.0, scratch);
    std::filesystem::remove(scratch);
    if (reference.top_out) {
      unit.stroke_zero = reference.top_out->zero;
      unit.stroke_zero_sd = reference.top_out->sd;
      daq::RecordZeros({.stroke = daq::MeasuredZero{unit.stroke_zero, unit.stroke_zero_sd}}, session);
    }
  }
  const ident::ParameterSet truth_values = truth.RecordedParameters(rig.model());
  const auto start = std::chrono::steady_clock::now();
  const double cpu = ThreadSeconds();
  const ident::SessionFit fit = ident::FitPrepared(
      ident::PrepareFitData(session, fmt::format("unit {}", unit.seed), model, fit_options.estimator.n), model,
      fit_options);
  unit.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  unit.cpu = ThreadSeconds() - cpu;
  // The fit alone (one thread), from the plan the entry point made: the figure of the target;
  // beside it the same fit without the calibration in its intervals (what that costs), the two in
  // turn first.
  const auto time = [&](const ident::EstimatorOptions& o) {
    const double before = ThreadSeconds();
    ident::Estimator(model, o).Fit(fit.data.experiments, fit.plan.start, fit.plan.choices, fit.data.issues);
    return ThreadSeconds() - before;
  };
  if (u % 2 == 0) {
    unit.estimator_cpu = time(fit_options.estimator);
    unit.uncalibrated_cpu = time(uncalibrated);
  } else {
    unit.uncalibrated_cpu = time(uncalibrated);
    unit.estimator_cpu = time(fit_options.estimator);
  }
  const ident::FitSummary& s = fit.summary;
  unit.verdict = s.Verdict();
  unit.converged = s.converged;
  for (const auto& c : s.channels) unit.worst_noise_ratio = std::max(unit.worst_noise_ratio, c.noise_ratio);
  for (int i : s.estimated_positions) {
    const std::string key = s.parameters.spec(i).key();
    unit.estimate.emplace_back(key, s.parameters.value(i));
    unit.sd.emplace_back(key, s.estimates[i].sd);
    if (const auto t = truth_values.find(key))
      unit.z.emplace_back(key, (s.parameters.value(i) - truth_values.value(*t)) / s.estimates[i].sd);
  }
  if (s.converged) Restart(fit, model, fit_options, truth_values, options.start_off, unit);
  return unit;
}

}  // namespace

UnitFit FitDrawnUnit(const UnitsOptions& options, int u) {
  ident::SessionFitOptions fit_options;
  fit_options.composition = options.base;
  const ident::Model model = ident::Model::Build(options.base, fit_options.causality);
  fit_options.estimator.gain_sd = options.gain_sd;
  ident::EstimatorOptions uncalibrated = fit_options.estimator;  // the fit's cost without the calibration
  uncalibrated.gain_sd.clear();
  return FitUnit(options, fit_options, uncalibrated, model, u);
}

UnitsStudy SummariseUnits(std::vector<UnitFit> units) {
  UnitsStudy out;
  std::map<std::string, std::vector<double>> zs;
  std::vector<double> seconds, cpu, estimator_cpu, uncalibrated_cpu, cost_ratio, ratios;
  for (const UnitFit& unit : units) {
    out.converged += unit.converged;
    out.at_floor += unit.verdict == ident::FitVerdict::kAtNoiseFloor;
    out.restarts += unit.restarted;
    out.same_optimum += unit.same_optimum;
    for (const auto& [key, z] : unit.z) zs[key].push_back(z);
    seconds.push_back(unit.seconds);
    ratios.push_back(unit.worst_noise_ratio);
    cpu.push_back(unit.cpu);
    estimator_cpu.push_back(unit.estimator_cpu);
    uncalibrated_cpu.push_back(unit.uncalibrated_cpu);
    cost_ratio.push_back(unit.estimator_cpu / unit.uncalibrated_cpu);
  }
  out.units = std::move(units);
  for (const auto& [key, z] : zs) {
    const ZCoverage c = SummariseZ(z);
    out.pooled_inside += c.inside;
    out.pooled_total += c.total;
    out.coverage[key] = c;
  }
  out.worst_ratio_median = Median(ratios);
  out.worst_ratio_max = ratios.empty() ? NAN : *std::max_element(ratios.begin(), ratios.end());
  out.seconds_median = Median(seconds);
  out.cpu_median = Median(cpu);
  out.estimator_cpu_median = Median(estimator_cpu);
  out.uncalibrated_cpu_median = Median(uncalibrated_cpu);
  out.cost_ratio_median = Median(cost_ratio);
  return out;
}

UnitsStudy RunUnitsStudy(const UnitsOptions& options, const std::function<void(const UnitFit&)>& on_unit) {
  std::vector<UnitFit> units;
  for (int u = 0; u < options.units; ++u) {
    units.push_back(FitDrawnUnit(options, u));
    if (on_unit) on_unit(units.back());
  }
  return SummariseUnits(std::move(units));
}

namespace {

nlohmann::json Pairs(const std::vector<std::pair<std::string, double>>& pairs) {
  nlohmann::json j = nlohmann::json::array();
  for (const auto& [key, v] : pairs) j.push_back({key, v});  // in order: the study's order of keys
  return j;
}

std::vector<std::pair<std::string, double>> PairsFrom(const nlohmann::json& j) {
  std::vector<std::pair<std::string, double>> out;
  for (const auto& p : j) out.emplace_back(p.at(0).get<std::string>(), p.at(1).get<double>());
  return out;
}

}  // namespace

nlohmann::json UnitFitJson(const UnitFit& u) {
  return {{"seed", u.seed},
          {"truth_composition", u.truth_composition},
          {"verdict", static_cast<int>(u.verdict)},
          {"verdict_text", ident::ToString(u.verdict)},
          {"converged", u.converged},
          {"worst_noise_ratio", u.worst_noise_ratio},
          {"z", Pairs(u.z)},
          {"estimate", Pairs(u.estimate)},
          {"sd", Pairs(u.sd)},
          {"stroke_zero", u.stroke_zero},
          {"stroke_zero_sd", u.stroke_zero_sd},
          {"restarted", u.restarted},
          {"same_optimum", u.same_optimum},
          {"restart_apart_sd", u.restart_apart_sd},
          {"restart_converged", u.restart_converged},
          {"restart_iterations", u.restart_iterations},
          {"restart_warning", u.restart_warning},
          {"timing", {{"seconds", u.seconds}, {"cpu", u.cpu}, {"estimator_cpu", u.estimator_cpu},
                      {"uncalibrated_cpu", u.uncalibrated_cpu}}}};
}

UnitFit UnitFitFromJson(const nlohmann::json& j) {
  UnitFit u;
  u.seed = j.at("seed").get<unsigned long>();
  u.truth_composition = j.at("truth_composition").get<std::string>();
  u.verdict = static_cast<ident::FitVerdict>(j.at("verdict").get<int>());
  u.converged = j.at("converged").get<bool>();
  u.worst_noise_ratio = j.at("worst_noise_ratio").get<double>();
  u.z = PairsFrom(j.at("z"));
  u.estimate = PairsFrom(j.at("estimate"));
  if (j.contains("sd")) u.sd = PairsFrom(j.at("sd"));
  u.stroke_zero = j.value("stroke_zero", 0.0);
  u.stroke_zero_sd = j.value("stroke_zero_sd", 0.0);
  u.restarted = j.at("restarted").get<bool>();
  u.same_optimum = j.at("same_optimum").get<bool>();
  u.restart_apart_sd = j.at("restart_apart_sd").get<double>();
  u.restart_converged = j.at("restart_converged").get<bool>();
  u.restart_iterations = j.at("restart_iterations").get<int>();
  u.restart_warning = j.at("restart_warning").get<std::string>();
  const nlohmann::json& t = j.at("timing");
  u.seconds = t.at("seconds").get<double>();
  u.cpu = t.at("cpu").get<double>();
  u.estimator_cpu = t.at("estimator_cpu").get<double>();
  u.uncalibrated_cpu = t.at("uncalibrated_cpu").get<double>();
  return u;
}

}  // namespace strut::study
