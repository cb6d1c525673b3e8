// strut bench drop: drop-test prediction on drawn units (issue 15's proof, docs/drop-prediction.md).
// Per unit: the standard shaker matrix simulated and fitted as strut identify would, the fit read
// back from its JSON, a drop of the unit's truth, and the drop predicted from the fit: errors of
// every figure, whether the truth is inside the 95 % intervals, the prediction's time. With
// --effect the truth has physics the fitted 2 dof model lacks, and each unit says which figures
// that physics moves.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "output_files.h"
#include "bench_support.h"
#include "strut/report/fit_report.h"
#include "strut/ident/session_fit.h"
#include "strut/sim/draw.h"
#include "strut/sim/drop_prediction.h"
#include "strut/sim/simulated_rig.h"
#include "option_checks.h"

namespace strut::tools {
namespace {

struct BenchDrop {
  int units = 10;
  unsigned long first_seed = 2000;
  double mass = 350.0, velocity = 0.5, duration = 30.0;
  std::vector<std::string> effects;
  std::string json_path;

  void Run() const {
    CheckOutputPath("--json", json_path, {});
    sim::UnitDraw draw;
    for (const std::string& e : effects) draw.effects.push_back({e, std::nullopt});
    draw.drop_mass = mass;
    draw.Validate();
    ident::SessionFitOptions options;  // the default fit: 2 dof, stroke input, default choices
    const ident::Model model = ident::Model::Build(options.composition, options.causality);
    const auto& names = sim::DropFigureNames();
    const int nf = static_cast<int>(names.size());
    std::vector<std::vector<double>> errors(nf);
    std::vector<long> inside(nf, 0), counted(nf, 0);
    std::vector<double> nominal_wall, nominal_cpu, total_wall, total_cpu;
    int fits = 0, at_floor = 0, within5 = 0;
    nlohmann::json rows = nlohmann::json::array();
    std::map<std::string, std::vector<std::string>> missing_words;
    std::cout << fmt::format("drop prediction from shaker fits of {} drawn 2dof units{} (seeds {}..): {} kg at {} m/s, "
                             "{} s\n",
                             units, effects.empty() ? "" : " with " + fmt::format("{}", fmt::join(effects, ", ")),
                             first_seed, mass, velocity, duration);
    for (int u = 0; u < units; ++u) {
      const unsigned long seed = first_seed + u;
      const sim::Truth truth = sim::DrawUnit(sim::WithIdealRig(sim::DefaultTruth()), draw, seed);
      const sim::SimulatedRig rig(truth);
      sim::RigRunOptions run;
      run.seed = seed;
      const daq::Session session = rig.RunMatrix(rig::StandardMatrixPlan(), run);
      const ident::SessionFit fit = ident::FitPrepared(
          ident::PrepareFitData(session, fmt::format("unit {}", seed), model, options.estimator.n), model, options);
      ++fits;
      const bool floor = fit.summary.Verdict() == ident::FitVerdict::kAtNoiseFloor;
      at_floor += floor;
      const ident::FitRecord record =
          ident::ParseFitJson(report::FitToJson(fit.summary), fmt::format("unit {}", seed), ident::Causality::kForceInput);

      // The truth's drop as the rig simulates it (clean: no sensors), its figures by the same code.
      std::mt19937_64 rng(seed);
      sim::DropRunReport truth_drop;
      sim::DropSpec spec{"drop", mass, velocity, duration};
      rig.RunDrop(spec, rng, &truth_drop);
      const sim::TransientResult& r = truth_drop.result;
      sim::DropTrace clean;
      clean.time = r.time;
      clean.stroke.assign(r.unknowns.row(0).begin(), r.unknowns.row(0).end());
      clean.force.assign(r.input.begin(), r.input.end());
      const Eigen::VectorXd p = r.channel("pressure");
      clean.pressure.assign(p.begin(), p.end());

      sim::DropPredictionOptions po;
      po.duration = duration;
      // The prediction alone (one run, what a 30 s drop costs), then with the intervals.
      po.intervals = false;
      double cpu = ThreadSeconds();
      const sim::DropPrediction single =
          sim::PredictDrop(record.model, record.parameters.values(), mass, velocity, {}, Eigen::MatrixXd(), po);
      nominal_cpu.push_back(ThreadSeconds() - cpu);
      nominal_wall.push_back(single.seconds);
      po.intervals = true;
      cpu = ThreadSeconds();
      const sim::DropPrediction pred = sim::PredictDrop(record.model, record.parameters.values(), mass, velocity,
                                                        record.estimated_positions, record.covariance, po);
      total_cpu.push_back(ThreadSeconds() - cpu);
      total_wall.push_back(pred.seconds);
      sim::DropFigures want = sim::MeasureDrop(clean, pred.figures.static_stroke, po.settle_band);
      const std::vector<double> got = sim::FigureValues(pred.figures), ref = sim::FigureValues(want);

      nlohmann::json row{{"seed", seed}, {"verdict", ident::ToString(fit.summary.Verdict())}};
      std::string line;
      for (int f = 0; f < nf; ++f) {
        if (std::string(names[f].name) == "static_stroke") continue;  // a model property, not measured
        // Times as differences (s): a peak at contact has time 0 in both. The rest relative.
        const bool time = std::string(names[f].unit) == "s";
        const double error = time ? got[f] - ref[f] : (got[f] - ref[f]) / std::abs(ref[f]);
        if (!std::isfinite(error)) continue;
        errors[f].push_back(error);
        const sim::FigureUncertainty& iv = pred.uncertainty[f];
        const bool in = ref[f] >= iv.lower && ref[f] <= iv.upper;
        if (std::isfinite(iv.sd)) {
          inside[f] += in;
          counted[f] += 1;
        }
        row[time ? "error_s" : "relative_error"][names[f].name] = error;
        row["inside"][names[f].name] = in;
      }
      const double ef = (got[0] - ref[0]) / ref[0], es = (got[2] - ref[2]) / ref[2];
      within5 += std::abs(ef) < 0.05 && std::abs(es) < 0.05;
      line = fmt::format("peak force {:+.2f} % ({}), max stroke {:+.2f} % ({}), final {:+.2f} %", 100 * ef,
                         row["inside"]["peak_force"].get<bool>() ? "in" : "OUT", 100 * es,
                         row["inside"]["max_stroke"].get<bool>() ? "in" : "OUT", 100 * (got[6] - ref[6]) / ref[6]);
      if (!effects.empty()) {
        const auto missing = sim::AttributeMissingPhysics(rig.model().composition(), rig.truth().Parameters(rig.model()),
                                                          record.model, mass, velocity, po);
        for (const auto& m : missing) {
          line += fmt::format("; {}: {}", m.term, m.affects);
          row["missing_physics"][m.term] = m.affects;
        }
      }
      std::cout << fmt::format("  unit {:5}: {:<17} {}; prediction {:.0f} ms CPU, with intervals ({} runs) {:.0f} ms\n",
                               seed, ident::ToString(fit.summary.Verdict()), line, 1e3 * nominal_cpu.back(),
                               pred.simulations, 1e3 * total_cpu.back());
      rows.push_back(row);
    }
    std::cout << fmt::format("\nfits at the noise floor {}/{}; peak force and max stroke both within 5 %: {}/{}\n",
                             at_floor, fits, within5, units);
    std::cout << "figure               median |error|   max |error|   truth inside 95 % interval (times: error in ms)\n";
    nlohmann::json summary = nlohmann::json::object();
    for (int f = 0; f < nf; ++f) {
      if (errors[f].empty()) continue;
      std::vector<double> a;
      for (double e : errors[f]) a.push_back(std::abs(e));
      const double med = Median(a), worst = *std::max_element(a.begin(), a.end());
      const bool time = std::string(names[f].unit) == "s";
      std::cout << fmt::format("  {:<20} {:8.3f} {}      {:8.3f} {}    {}/{}\n", names[f].name, (time ? 1e3 : 100) * med,
                               time ? "ms" : "% ", (time ? 1e3 : 100) * worst, time ? "ms" : "% ", inside[f], counted[f]);
      summary[names[f].name] = {{"median_abs_error", med}, {"max_abs_error", worst}, {"inside", inside[f]},
                                {"counted", counted[f]}};
    }
    std::cout << fmt::format(
        "a {} s drop prediction: median {:.0f} ms CPU ({:.0f} ms wall), target < 1 s; with intervals median {:.0f} ms "
        "CPU ({:.0f} ms wall)\n",
        duration, 1e3 * Median(nominal_cpu), 1e3 * Median(nominal_wall), 1e3 * Median(total_cpu),
        1e3 * Median(total_wall));
    if (!json_path.empty())
      WriteTextOutput(json_path, nlohmann::json{{"units", rows},
                                                {"figures", summary},
                                                {"at_noise_floor", at_floor},
                                                {"within_5_percent", within5},
                                                {"prediction_cpu_median_s", Median(nominal_cpu)},
                                                {"prediction_wall_median_s", Median(nominal_wall)},
                                                {"with_intervals_cpu_median_s", Median(total_cpu)},
                                                {"with_intervals_wall_median_s", Median(total_wall)}}
                                         .dump(1) + "\n");
  }
};

}  // namespace

void RegisterBenchDrop(CLI::App& bench) {
  auto command = std::make_shared<BenchDrop>();
  CLI::App* sub = bench.add_subcommand(
      "drop", "Drop prediction from shaker fits of drawn units: errors against the truth's drop, interval coverage, "
              "prediction time.");
  sub->add_option("--units", command->units, "Number of drawn units.")->check(Between(1, 10000))->capture_default_str();
  sub->add_option("--first-seed", command->first_seed, "Seed of the first unit (the others follow).")->capture_default_str();
  sub->add_option("--mass", command->mass, "Dropped mass, kg.")->check(Positive("kg"))->capture_default_str();
  sub->add_option("--velocity", command->velocity, "Stroke velocity at contact, m/s.")
      ->check(NonNegative())
      ->capture_default_str();
  sub->add_option("--duration", command->duration, "Seconds from contact.")->check(Between(0.1, 3600.0))->capture_default_str();
  sub->add_option("--effect", command->effects,
                  "An effect the truth has and the fitted 2dof model lacks (drawn size): oil-compressibility, "
                  "viscous-damping, stribeck-friction, end-stop, real-gas; repeatable.");
  sub->add_option("--json", command->json_path, "Also write the figures as JSON to this file.");
  sub->callback([command] { command->Run(); });
}

}  // namespace strut::tools
