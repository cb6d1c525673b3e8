#include "strut/study/drop.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "strut/ident/fit_record.h"
#include "strut/ident/session_fit.h"
#include "strut/report/fit_report.h"
#include "strut/sim/draw.h"
#include "strut/sim/drop_prediction.h"
#include "strut/sim/simulated_rig.h"
#include "strut/study/cpu_time.h"
#include "strut/study/statistics.h"

namespace strut::study {
namespace {

//! The truth's drop as the rig simulates it (clean: no sensors).
sim::DropTrace TruthDrop(const sim::SimulatedRig& rig, const DropOptions& options, unsigned long seed) {
  std::mt19937_64 rng(seed);
  sim::DropRunReport truth_drop;
  sim::DropSpec spec{"drop", options.mass, options.velocity, options.duration};
  rig.RunDrop(spec, rng, &truth_drop);
  const sim::TransientResult& r = truth_drop.result;
  sim::DropTrace clean;
  clean.time = r.time;
  clean.stroke.assign(r.unknowns.row(0).begin(), r.unknowns.row(0).end());
  clean.force.assign(r.input.begin(), r.input.end());
  const Eigen::VectorXd p = r.channel("pressure");
  clean.pressure.assign(p.begin(), p.end());
  return clean;
}

//! The predicted figures against the truth's, by the same code.
void CompareFigures(const sim::DropPrediction& pred, const sim::DropFigures& want, DropUnit& unit) {
  const auto& names = sim::DropFigureNames();
  const std::vector<double> got = sim::FigureValues(pred.figures), ref = sim::FigureValues(want);
  for (std::size_t f = 0; f < names.size(); ++f) {
    if (std::string(names[f].name) == "static_stroke") continue;  // a model property, not measured
    // Times as differences (s): a peak at contact has time 0 in both. The rest relative.
    const bool time = std::string(names[f].unit) == "s";
    const double error = time ? got[f] - ref[f] : (got[f] - ref[f]) / std::abs(ref[f]);
    if (!std::isfinite(error)) continue;
    const sim::FigureUncertainty& iv = pred.uncertainty[f];
    const bool in = ref[f] >= iv.lower && ref[f] <= iv.upper;
    unit.figures.push_back({names[f].name, time, error, in, std::isfinite(iv.sd)});
    if (f == 0) unit.peak_force_inside = in;
    if (f == 2) unit.max_stroke_inside = in;
  }
  unit.peak_force_error = (got[0] - ref[0]) / ref[0];
  unit.max_stroke_error = (got[2] - ref[2]) / ref[2];
  unit.final_stroke_error = (got[6] - ref[6]) / ref[6];
}

DropUnit PredictUnit(const DropOptions& options, const sim::UnitDraw& draw, const ident::SessionFitOptions& fit_options,
                     const ident::Model& model, unsigned long seed) {
  DropUnit unit;
  unit.seed = seed;
  const sim::Truth truth = sim::DrawUnit(sim::WithIdealRig(sim::DefaultTruth()), draw, seed);
  const sim::SimulatedRig rig(truth);
  sim::RigRunOptions run;
  run.seed = seed;
  const daq::Session session = rig.RunMatrix(rig::StandardMatrixPlan(), run);
  const ident::SessionFit fit = ident::FitPrepared(
      ident::PrepareFitData(session, fmt::format("unit {}", seed), model, fit_options.estimator.n), model, fit_options);
  unit.verdict = fit.summary.Verdict();
  const ident::FitRecord record =
      ident::ParseFitJson(report::FitToJson(fit.summary), fmt::format("unit {}", seed), ident::Causality::kForceInput);
  const sim::DropTrace clean = TruthDrop(rig, options, seed);

  sim::DropPredictionOptions po;
  po.duration = options.duration;
  // The prediction alone (one run, what a 30 s drop costs), then with the intervals.
  po.intervals = false;
  double cpu = ThreadSeconds();
  const sim::DropPrediction single = sim::PredictDrop(record.model, record.parameters.values(), options.mass,
                                                      options.velocity, {}, Eigen::MatrixXd(), po);
  unit.cpu = ThreadSeconds() - cpu;
  unit.wall = single.seconds;
  po.intervals = true;
  cpu = ThreadSeconds();
  const sim::DropPrediction pred = sim::PredictDrop(record.model, record.parameters.values(), options.mass,
                                                    options.velocity, record.estimated_positions, record.covariance, po);
  unit.intervals_cpu = ThreadSeconds() - cpu;
  unit.intervals_wall = pred.seconds;
  unit.simulations = pred.simulations;
  CompareFigures(pred, sim::MeasureDrop(clean, pred.figures.static_stroke, po.settle_band), unit);
  if (!options.effects.empty())
    for (const auto& m : sim::AttributeMissingPhysics(rig.model().composition(), rig.truth().Parameters(rig.model()),
                                                      record.model, options.mass, options.velocity, po))
      unit.missing_physics.emplace_back(m.term, m.affects);
  return unit;
}

}  // namespace

DropUnit PredictDropUnit(const DropOptions& options, int u) {
  sim::UnitDraw draw;
  for (const std::string& e : options.effects) draw.effects.push_back({e, std::nullopt});
  draw.drop_mass = options.mass;
  draw.Validate();
  const ident::SessionFitOptions fit_options;  // the default fit: 2 dof, stroke input, default choices
  const ident::Model model = ident::Model::Build(fit_options.composition, fit_options.causality);
  return PredictUnit(options, draw, fit_options, model, options.first_seed + u);
}

DropStudy SummariseDrop(std::vector<DropUnit> units) {
  DropStudy study;
  std::vector<double> cpu, wall, intervals_cpu, intervals_wall;
  for (const DropUnit& unit : units) {
    ++study.fits;
    study.at_floor += unit.verdict == ident::FitVerdict::kAtNoiseFloor;
    study.within5 += std::abs(unit.peak_force_error) < 0.05 && std::abs(unit.max_stroke_error) < 0.05;
    cpu.push_back(unit.cpu);
    wall.push_back(unit.wall);
    intervals_cpu.push_back(unit.intervals_cpu);
    intervals_wall.push_back(unit.intervals_wall);
  }
  study.units = std::move(units);
  for (const sim::DropFigureName& name : sim::DropFigureNames()) {
    DropFigureSummary s{name.name, std::string(name.unit) == "s"};
    std::vector<double> errors;
    for (const DropUnit& unit : study.units)
      for (const DropFigureError& f : unit.figures)
        if (f.name == s.name) {
          errors.push_back(std::abs(f.error));
          s.inside += f.has_interval && f.inside;
          s.counted += f.has_interval;
        }
    if (errors.empty()) continue;
    s.median_abs_error = Median(errors);
    s.max_abs_error = *std::max_element(errors.begin(), errors.end());
    study.figures.push_back(s);
  }
  study.cpu_median = Median(cpu);
  study.wall_median = Median(wall);
  study.intervals_cpu_median = Median(intervals_cpu);
  study.intervals_wall_median = Median(intervals_wall);
  return study;
}

DropStudy RunDropStudy(const DropOptions& options, const std::function<void(const DropUnit&)>& on_unit) {
  std::vector<DropUnit> units;
  for (int u = 0; u < options.units; ++u) {
    units.push_back(PredictDropUnit(options, u));
    if (on_unit) on_unit(units.back());
  }
  return SummariseDrop(std::move(units));
}

}  // namespace strut::study
