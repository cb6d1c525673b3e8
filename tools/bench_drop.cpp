// strut bench drop: drop-test prediction on drawn units (issue 15's proof, docs/drop-prediction.md;
// study::RunDropStudy): errors of every figure against the truth's drop, interval coverage, the
// prediction's time, and with --effect which figures the physics the fit lacks moves.
#include <fmt/ranges.h>

#include <iostream>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "bench_options.h"
#include "option_checks.h"
#include "output_files.h"
#include "strut/study/drop.h"

namespace strut::tools {
namespace {

void PrintUnit(const study::DropUnit& u) {
  std::string line = fmt::format("peak force {:+.2f} % ({}), max stroke {:+.2f} % ({}), final {:+.2f} %",
                                 100 * u.peak_force_error, u.peak_force_inside ? "in" : "OUT", 100 * u.max_stroke_error,
                                 u.max_stroke_inside ? "in" : "OUT", 100 * u.final_stroke_error);
  for (const auto& [term, affects] : u.missing_physics) line += fmt::format("; {}: {}", term, affects);
  std::cout << fmt::format("  unit {:5}: {:<17} {}; prediction {:.0f} ms CPU, with intervals ({} runs) {:.0f} ms\n",
                           u.seed, ident::ToString(u.verdict), line, 1e3 * u.cpu, u.simulations, 1e3 * u.intervals_cpu);
}

nlohmann::json UnitJson(const study::DropUnit& u) {
  nlohmann::json row{{"seed", u.seed}, {"verdict", ident::ToString(u.verdict)}};
  for (const study::DropFigureError& f : u.figures) {
    row[f.time ? "error_s" : "relative_error"][f.name] = f.error;
    row["inside"][f.name] = f.inside;
  }
  for (const auto& [term, affects] : u.missing_physics) row["missing_physics"][term] = affects;
  return row;
}

struct BenchDrop {
  study::DropOptions options;
  std::string json_path;

  void Run() const {
    CheckOutputPath("--json", json_path, {});
    const study::DropOptions& o = options;
    std::cout << fmt::format("drop prediction from shaker fits of {} drawn 2dof units{} (seeds {}..): {} kg at {} m/s, "
                             "{} s\n",
                             o.units, o.effects.empty() ? "" : " with " + fmt::format("{}", fmt::join(o.effects, ", ")),
                             o.first_seed, o.mass, o.velocity, o.duration);
    const study::DropStudy s = study::RunDropStudy(o, PrintUnit);
    std::cout << fmt::format("\nfits at the noise floor {}/{}; peak force and max stroke both within 5 %: {}/{}\n",
                             s.at_floor, s.fits, s.within5, o.units);
    std::cout << "figure               median |error|   max |error|   truth inside 95 % interval (times: error in ms)\n";
    nlohmann::json summary = nlohmann::json::object();
    for (const study::DropFigureSummary& f : s.figures) {
      std::cout << fmt::format("  {:<20} {:8.3f} {}      {:8.3f} {}    {}/{}\n", f.name,
                               (f.time ? 1e3 : 100) * f.median_abs_error, f.time ? "ms" : "% ",
                               (f.time ? 1e3 : 100) * f.max_abs_error, f.time ? "ms" : "% ", f.inside, f.counted);
      summary[f.name] = {{"median_abs_error", f.median_abs_error}, {"max_abs_error", f.max_abs_error},
                         {"inside", f.inside}, {"counted", f.counted}};
    }
    std::cout << fmt::format(
        "a {} s drop prediction: median {:.0f} ms CPU ({:.0f} ms wall), target < 1 s; with intervals median {:.0f} ms "
        "CPU ({:.0f} ms wall)\n",
        o.duration, 1e3 * s.cpu_median, 1e3 * s.wall_median, 1e3 * s.intervals_cpu_median, 1e3 * s.intervals_wall_median);
    if (json_path.empty()) return;
    nlohmann::json rows = nlohmann::json::array();
    for (const study::DropUnit& u : s.units) rows.push_back(UnitJson(u));
    WriteJsonOutput(json_path, nlohmann::json{{"units", rows},
                                              {"figures", summary},
                                              {"at_noise_floor", s.at_floor},
                                              {"within_5_percent", s.within5},
                                              {"prediction_cpu_median_s", s.cpu_median},
                                              {"prediction_wall_median_s", s.wall_median},
                                              {"with_intervals_cpu_median_s", s.intervals_cpu_median},
                                              {"with_intervals_wall_median_s", s.intervals_wall_median}});
  }
};

}  // namespace

void RegisterBenchDrop(CLI::App& bench) {
  auto [sub, command] = AddCommand<BenchDrop>(
      bench, "drop",
      "Drop prediction from shaker fits of drawn units: errors against the truth's drop, interval coverage, "
      "prediction time.");
  AddDropBenchOptions(*sub, command->options, "Seconds from contact.");
  sub->add_option("--effect", command->options.effects,
                  "An effect the truth has and the fitted 2dof model lacks (drawn size): oil-compressibility, "
                  "viscous-damping, stribeck-friction, end-stop, real-gas; repeatable.");
  sub->add_option("--json", command->json_path, "Also write the figures as JSON to this file.");
}

}  // namespace strut::tools
