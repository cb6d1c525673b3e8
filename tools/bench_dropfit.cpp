// strut bench dropfit: what one drop adds to a shaker fit (issue 15, docs/drop-prediction.md "Drop
// records in the fit"). Per drawn unit: the standard shaker matrix fitted alone and with one drop of
// the same unit, both as strut identify fits them; theta3's sd side by side (the ratio), whether the
// truth is inside each fit's 95 % intervals, and the drop predicted from each fit against the
// truth's drop (the maximum stroke the shaker fit under-predicts).
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>

#include "bench_support.h"
#include "commands.h"
#include "option_checks.h"
#include "output_files.h"
#include "strut/report/fit_report.h"
#include "strut/ident/session_fit.h"
#include "strut/sim/draw.h"
#include "strut/sim/drop_fit.h"
#include "strut/sim/drop_prediction.h"
#include "strut/sim/simulated_rig.h"

namespace strut::tools {
namespace {

//! One fit of a unit as the bench reports it.
struct FitFigures {
  std::string verdict;
  double theta3 = NAN, theta3_sd = NAN, z = NAN;  //!< z: (estimate - truth) / sd
  int inside = 0, estimated = 0;                  //!< estimated parameters with the truth inside the 95 % interval
  double max_stroke_error = NAN, peak_force_error = NAN;  //!< relative, the drop predicted from this fit
  bool max_stroke_inside = false;
  //! The max stroke error (relative) split over the estimated parameters, linearised: the
  //! prediction's gradient times each estimate's error (key, share), largest first.
  std::vector<std::pair<std::string, double>> max_stroke_terms;
  std::map<std::string, double> z_of;  //!< per estimated parameter, (estimate - truth) / sd
  double cpu = 0.0;  //!< s of this thread for the fit
  nlohmann::json Json() const {
    return {{"verdict", verdict},          {"theta3", theta3},
            {"theta3_sd", theta3_sd},      {"theta3_z", z},
            {"inside_95", inside},         {"estimated", estimated},
            {"max_stroke_error", max_stroke_error}, {"max_stroke_inside", max_stroke_inside},
            {"peak_force_error", peak_force_error}, {"fit_cpu_s", cpu},
            {"max_stroke_error_terms", max_stroke_terms}};
  }
};

struct BenchDropFit {
  int units = 10;
  unsigned long first_seed = 2000;
  double mass = 350.0, velocity = 0.5, duration = 10.0;
  std::string json_path;

  FitFigures Figures(const ident::SessionFit& fit, const ident::ParameterSet& truth, const sim::DropFigures& want,
                     double cpu) const {
    FitFigures f;
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
    po.duration = duration;
    const sim::DropPrediction p = sim::PredictDrop(record.model, record.parameters.values(), mass, velocity,
                                                   record.estimated_positions, record.covariance, po);
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

  void Run() const {
    CheckOutputPath("--json", json_path, {});
    ident::SessionFitOptions shaker;  // the default fit: 2 dof, stroke input, default choices
    ident::SessionFitOptions with_drop = shaker;
    with_drop.estimator.transient_predictor = sim::DropPredictorFactory();
    const ident::Model model = ident::Model::Build(shaker.composition, shaker.causality);
    std::cout << fmt::format("theta3 from the shaker matrix alone and with one drop ({} kg at {} m/s, {} s) of {} drawn "
                             "2dof units on the ideal rig (seeds {}..)\n",
                             mass, velocity, duration, units, first_seed);
    std::cout << "  unit   shaker alone: theta3 +- sd (z)      with the drop: theta3 +- sd (z)    sd ratio  "
                 "in 95 %  max stroke error (alone / with)\n";
    std::vector<double> ratios, cpu_alone, cpu_with, stroke_alone, stroke_with;
    std::map<std::string, std::vector<double>> terms_alone;  // per parameter, its share of each unit's max stroke error
    std::map<std::string, std::vector<double>> z_alone;      // per parameter, the shaker fit's z of each unit
    int in3_alone = 0, in3_with = 0, inside_alone = 0, inside_with = 0, estimated_alone = 0, estimated_with = 0;
    int floor_alone = 0, floor_with = 0, stroke_in_alone = 0, stroke_in_with = 0;
    nlohmann::json rows = nlohmann::json::array();
    for (int u = 0; u < units; ++u) {
      const unsigned long seed = first_seed + u;
      const sim::Truth truth = sim::DrawUnit(sim::WithIdealRig(sim::DefaultTruth()), sim::UnitDraw{}, seed);
      const sim::SimulatedRig rig(truth);
      sim::RigRunOptions run;
      run.seed = seed;
      const daq::Session matrix = rig.RunMatrix(rig::StandardMatrixPlan(), run);
      daq::Session both = matrix;
      sim::DropRunReport truth_drop;
      both.experiments.push_back(rig.RunDropSession(sim::DropSpec{"drop", mass, velocity, duration}, run, &truth_drop)
                                     .experiments[0]);
      // The truth's drop without sensors: the reference of the predicted figures.
      const sim::TransientResult& r = truth_drop.result;
      sim::DropTrace clean;
      clean.time = r.time;
      clean.stroke.assign(r.unknowns.row(0).begin(), r.unknowns.row(0).end());
      clean.force.assign(r.input.begin(), r.input.end());
      const sim::DropFigures want = sim::MeasureDrop(clean, NAN, 0.01);
      const ident::ParameterSet truth_values = truth.Parameters(rig.model());
      const std::string name = fmt::format("unit {}", seed);

      double cpu = ThreadSeconds();
      const ident::SessionFit alone =
          ident::FitPrepared(ident::PrepareFitData(matrix, name, model, shaker.estimator.n), model, shaker);
      const FitFigures a = Figures(alone, truth_values, want, ThreadSeconds() - cpu);
      cpu = ThreadSeconds();
      const ident::SessionFit joint =
          ident::FitPrepared(ident::PrepareFitData(both, name, model, with_drop.estimator.n), model, with_drop);
      const FitFigures b = Figures(joint, truth_values, want, ThreadSeconds() - cpu);

      const double ratio = a.theta3_sd / b.theta3_sd;
      ratios.push_back(ratio);
      cpu_alone.push_back(a.cpu);
      cpu_with.push_back(b.cpu);
      stroke_alone.push_back(a.max_stroke_error);
      stroke_with.push_back(b.max_stroke_error);
      for (const auto& [key, term] : a.max_stroke_terms) terms_alone[key].push_back(term);
      for (const auto& [key, z] : a.z_of) z_alone[key].push_back(z);
      in3_alone += std::abs(a.z) <= 1.96;
      in3_with += std::abs(b.z) <= 1.96;
      inside_alone += a.inside;
      inside_with += b.inside;
      estimated_alone += a.estimated;
      estimated_with += b.estimated;
      floor_alone += a.verdict == "at-noise-floor";
      floor_with += b.verdict == "at-noise-floor";
      stroke_in_alone += a.max_stroke_inside;
      stroke_in_with += b.max_stroke_inside;
      std::cout << fmt::format("  {:5}  {:8.1f} +- {:5.1f} ({:+.2f})          {:8.1f} +- {:5.2f} ({:+.2f})      {:6.1f}"
                               "    {:2}/{:2} {:2}/{:2}  {:+.2f} % / {:+.2f} %{}\n",
                               seed, a.theta3, a.theta3_sd, a.z, b.theta3, b.theta3_sd, b.z, ratio, a.inside, a.estimated,
                               b.inside, b.estimated, 100 * a.max_stroke_error, 100 * b.max_stroke_error,
                               a.verdict == "at-noise-floor" && b.verdict == "at-noise-floor"
                                   ? ""
                                   : fmt::format("  ({} / {})", a.verdict, b.verdict));
      std::string largest_terms;
      for (std::size_t k = 0; k < std::min<std::size_t>(3, a.max_stroke_terms.size()); ++k)
        largest_terms += fmt::format("{}{} {:+.2f} % (its z {:+.2f})", k ? ", " : "", a.max_stroke_terms[k].first,
                                     100 * a.max_stroke_terms[k].second, a.z_of.at(a.max_stroke_terms[k].first));
      // The stroke zero moves no figure of a drop directly (the drop starts at the true zero), but
      // the shaker fit cannot tell it from theta5, theta6: its z says where their errors come from.
      const auto zero = a.z_of.find("theta12");
      std::cout << fmt::format("         the shaker fit's max stroke error from its estimates' errors: {}{}\n",
                               largest_terms,
                               zero == a.z_of.end() ? "" : fmt::format("; stroke zero theta12 z {:+.2f}", zero->second));
      rows.push_back({{"seed", seed},
                      {"theta3_truth", truth_values.value(*truth_values.find("theta3"))},
                      {"shaker", a.Json()},
                      {"shaker_and_drop", b.Json()},
                      {"theta3_sd_ratio", ratio}});
    }
    const auto [low, high] = std::minmax_element(ratios.begin(), ratios.end());
    const auto under = [](const std::vector<double>& v) { return std::count_if(v.begin(), v.end(), [](double e) { return e < 0; }); };
    const auto largest = [](const std::vector<double>& v) {
      double m = 0.0;
      for (double e : v) m = std::max(m, std::abs(e));
      return m;
    };
    std::cout << fmt::format(
        "\ntheta3 sd, shaker alone over shaker and drop: median {:.1f}, range {:.1f} .. {:.1f}\n"
        "truth inside the 95 % interval of theta3: alone {}/{}, with the drop {}/{}; of every estimated parameter: "
        "alone {}/{}, with the drop {}/{}\n"
        "fits at the noise floor: alone {}/{}, with the drop {}/{}\n"
        "max stroke of the predicted drop: median error alone {:+.2f} % (largest {:.2f} %, under-predicted on {}/{}, "
        "truth inside the interval {}/{}); with the drop {:+.2f} % (largest {:.2f} %, under-predicted on {}/{}, inside "
        "{}/{})\n"
        "fit time (CPU of one thread): median alone {:.1f} s, with the drop {:.1f} s\n",
        Median(ratios), *low, *high, in3_alone, units, in3_with, units, inside_alone, estimated_alone, inside_with,
        estimated_with, floor_alone, units, floor_with, units, 100 * Median(stroke_alone), 100 * largest(stroke_alone),
        under(stroke_alone), units, stroke_in_alone, units, 100 * Median(stroke_with), 100 * largest(stroke_with),
        under(stroke_with), units, stroke_in_with, units, Median(cpu_alone), Median(cpu_with));
    std::vector<std::pair<double, std::string>> medians;
    for (const auto& [key, v] : terms_alone) medians.emplace_back(Median(v), key);
    std::sort(medians.begin(), medians.end(), [](const auto& x, const auto& y) { return std::abs(x.first) > std::abs(y.first); });
    std::string split;
    for (std::size_t k = 0; k < std::min<std::size_t>(4, medians.size()); ++k)
      split += fmt::format("{}{} {:+.2f} % (median z {:+.2f})", k ? ", " : "", medians[k].second, 100 * medians[k].first,
                           Median(z_alone[medians[k].second]));
    std::cout << fmt::format("shaker alone's max stroke error, linearised over its estimates' errors (median per "
                             "parameter): {}; the stroke zero theta12: median z {:+.2f}\n",
                             split, Median(z_alone["theta12"]));
    if (!json_path.empty())
      WriteTextOutput(json_path, nlohmann::json{{"units", rows},
                                                {"theta3_sd_ratio_median", Median(ratios)},
                                                {"theta3_sd_ratio_min", *low},
                                                {"theta3_sd_ratio_max", *high},
                                                {"theta3_inside_alone", in3_alone},
                                                {"theta3_inside_with_drop", in3_with},
                                                {"inside_alone", inside_alone},
                                                {"inside_with_drop", inside_with},
                                                {"estimated_alone", estimated_alone},
                                                {"estimated_with_drop", estimated_with}}
                                         .dump(1) + "\n");
  }
};

}  // namespace

void RegisterBenchDropFit(CLI::App& bench) {
  auto command = std::make_shared<BenchDropFit>();
  CLI::App* sub = bench.add_subcommand(
      "dropfit", "What one drop adds to a shaker fit on drawn units: theta3's sd alone and with the drop, interval "
                 "coverage, and the drop predicted from each fit.");
  sub->add_option("--units", command->units, "Number of drawn units.")->check(Between(1, 10000))->capture_default_str();
  sub->add_option("--first-seed", command->first_seed, "Seed of the first unit (the others follow).")->capture_default_str();
  sub->add_option("--mass", command->mass, "Dropped mass, kg.")->check(Positive("kg"))->capture_default_str();
  sub->add_option("--velocity", command->velocity, "Stroke velocity at contact, m/s.")
      ->check(NonNegative())
      ->capture_default_str();
  sub->add_option("--duration", command->duration, "Seconds of the drop record from contact.")
      ->check(Between(0.1, 3600.0))
      ->capture_default_str();
  sub->add_option("--json", command->json_path, "Also write the figures as JSON to this file.");
  sub->callback([command] { command->Run(); });
}

}  // namespace strut::tools
