#include "strut/study/drop_fit.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "strut/ident/fit_record.h"
#include "strut/ident/session_fit.h"
#include "strut/report/fit_report.h"
#include "strut/sim/draw.h"
#include "strut/sim/drop_fit.h"
#include "strut/sim/drop_prediction.h"
#include "strut/sim/simulated_rig.h"
#include "strut/study/cpu_time.h"
#include "strut/study/statistics.h"

namespace strut::study {
namespace {

DropFitFigures Figures(const DropFitOptions& options, const ident::SessionFit& fit, const ident::ParameterSet& truth,
                       const sim::DropFigures& want, double cpu) {
  DropFitFigures f;
  const ident::FitSummary& s = fit.summary;
  f.verdict = ident::ToString(s.Verdict());
  f.cpu = cpu;
  for (int i = 0; i < s.parameters.size(); ++i) {
    if (!s.estimates[i].estimated) continue;
    const double t = truth.value(*truth.find(s.parameters.spec(i).key()));
    ++f.estimated;
    f.z_of[s.parameters.spec(i).key()] = (s.parameters.value(i) - t) / s.estimates[i].sd;
    f.inside += std::abs(s.parameters.value(i) - t) <= 1.96 * s.estimates[i].sd;
    if (s.parameters.spec(i).index == 3) {
      f.theta3 = s.parameters.value(i);
      f.theta3_sd = s.estimates[i].sd;
      f.z = (f.theta3 - t) / f.theta3_sd;
    }
  }
  // The drop predicted from this fit as strut predict drop does (through its JSON).
  const ident::FitRecord record = ident::ParseFitJson(report::FitToJson(s), "fit", ident::Causality::kForceInput);
  sim::DropPredictionOptions po;
  po.duration = options.duration;
  const sim::DropPrediction p = sim::PredictDrop(record.model, record.parameters.values(), options.mass,
                                                 options.velocity, record.estimated_positions, record.covariance, po);
  f.max_stroke_error = (p.figures.max_stroke - want.max_stroke) / want.max_stroke;
  f.peak_force_error = (p.figures.peak_force - want.peak_force) / want.peak_force;
  f.max_stroke_inside = want.max_stroke >= p.uncertainty[2].lower && want.max_stroke <= p.uncertainty[2].upper;
  for (std::size_t a = 0; a < p.interval_parameters.size(); ++a) {
    const std::string& key = p.interval_parameters[a];
    const double error = record.parameters.value(*record.parameters.find(key)) - truth.value(*truth.find(key));
    f.max_stroke_terms.emplace_back(key, p.gradient(2, static_cast<Eigen::Index>(a)) * error / want.max_stroke);
  }
  std::sort(f.max_stroke_terms.begin(), f.max_stroke_terms.end(),
            [](const auto& x, const auto& y) { return std::abs(x.second) > std::abs(y.second); });
  return f;
}

DropFitUnit FitUnit(const DropFitOptions& options, const ident::SessionFitOptions& shaker,
                    const ident::SessionFitOptions& with_drop, const ident::Model& model, unsigned long seed) {
  const sim::Truth truth = sim::DrawUnit(sim::WithIdealRig(sim::DefaultTruth()), sim::UnitDraw{}, seed);
  const sim::SimulatedRig rig(truth);
  sim::RigRunOptions run;
  run.seed = seed;
  const daq::Session matrix = rig.RunMatrix(rig::StandardMatrixPlan(), run);
  daq::Session both = matrix;
  sim::DropRunReport truth_drop;
  both.experiments.push_back(
      rig.RunDropSession(sim::DropSpec{"drop", options.mass, options.velocity, options.duration}, run, &truth_drop)
          .experiments[0]);
  // The truth's drop without sensors: the reference of the predicted figures.
  const sim::TransientResult& r = truth_drop.result;
  sim::DropTrace clean;
  clean.time = r.time;
  clean.stroke.assign(r.unknowns.row(0).begin(), r.unknowns.row(0).end());
  clean.force.assign(r.input.begin(), r.input.end());
  const sim::DropFigures want = sim::MeasureDrop(clean, NAN, 0.01);
  const ident::ParameterSet truth_values = truth.RecordedParameters(rig.model());
  const std::string name = fmt::format("unit {}", seed);

  DropFitUnit unit;
  unit.seed = seed;
  unit.theta3_truth = truth_values.value(*truth_values.find("theta3"));
  double cpu = ThreadSeconds();
  const ident::SessionFit alone =
      ident::FitPrepared(ident::PrepareFitData(matrix, name, model, shaker.estimator.n), model, shaker);
  unit.alone = Figures(options, alone, truth_values, want, ThreadSeconds() - cpu);
  cpu = ThreadSeconds();
  const ident::SessionFit joint =
      ident::FitPrepared(ident::PrepareFitData(both, name, model, with_drop.estimator.n), model, with_drop);
  unit.with_drop = Figures(options, joint, truth_values, want, ThreadSeconds() - cpu);
  unit.theta3_sd_ratio = unit.alone.theta3_sd / unit.with_drop.theta3_sd;
  return unit;
}

DropFitSide Summarise(const std::vector<DropFitUnit>& units, DropFitFigures DropFitUnit::*side) {
  DropFitSide s;
  std::vector<double> stroke, cpu;
  for (const DropFitUnit& u : units) {
    const DropFitFigures& f = u.*side;
    s.theta3_inside += std::abs(f.z) <= 1.96;
    s.inside += f.inside;
    s.estimated += f.estimated;
    s.at_floor += f.verdict == "at-noise-floor";
    s.max_stroke_inside += f.max_stroke_inside;
    s.max_stroke_under += f.max_stroke_error < 0;
    s.max_stroke_error_largest = std::max(s.max_stroke_error_largest, std::abs(f.max_stroke_error));
    stroke.push_back(f.max_stroke_error);
    cpu.push_back(f.cpu);
  }
  s.max_stroke_error_median = Median(stroke);
  s.cpu_median = Median(cpu);
  return s;
}

}  // namespace

DropFitStudy RunDropFitStudy(const DropFitOptions& options, const std::function<void(const DropFitUnit&)>& on_unit) {
  const ident::SessionFitOptions shaker;  // the default fit: 2 dof, stroke input, default choices
  ident::SessionFitOptions with_drop = shaker;
  with_drop.estimator.transient_predictor = sim::DropPredictorFactory();
  const ident::Model model = ident::Model::Build(shaker.composition, shaker.causality);
  DropFitStudy study;
  std::vector<double> ratios;
  std::map<std::string, std::vector<double>> terms_alone;  // per parameter, its share of each unit's max stroke error
  std::map<std::string, std::vector<double>> z_alone;      // per parameter, the shaker fit's z of each unit
  for (int u = 0; u < options.units; ++u) {
    DropFitUnit unit = FitUnit(options, shaker, with_drop, model, options.first_seed + u);
    ratios.push_back(unit.theta3_sd_ratio);
    for (const auto& [key, term] : unit.alone.max_stroke_terms) terms_alone[key].push_back(term);
    for (const auto& [key, z] : unit.alone.z_of) z_alone[key].push_back(z);
    if (on_unit) on_unit(unit);
    study.units.push_back(std::move(unit));
  }
  study.alone = Summarise(study.units, &DropFitUnit::alone);
  study.with_drop = Summarise(study.units, &DropFitUnit::with_drop);
  study.ratio_median = Median(ratios);
  if (!ratios.empty()) {
    const auto [low, high] = std::minmax_element(ratios.begin(), ratios.end());
    study.ratio_min = *low;
    study.ratio_max = *high;
  }
  for (const auto& [key, v] : terms_alone) study.alone_terms.emplace_back(Median(v), key);
  std::sort(study.alone_terms.begin(), study.alone_terms.end(),
            [](const auto& x, const auto& y) { return std::abs(x.first) > std::abs(y.first); });
  for (const auto& [key, v] : z_alone) study.alone_median_z[key] = Median(v);
  return study;
}

}  // namespace strut::study
