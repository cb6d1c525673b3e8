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
    std::cout << study::DropHeading(o);
    const study::DropStudy s =
        study::RunDropStudy(o, [](const study::DropUnit& u) { std::cout << study::DropUnitLine(u); });
    std::cout << study::DropSummary(o, s);
    nlohmann::json summary = nlohmann::json::object();
    for (const study::DropFigureSummary& f : s.figures)
      summary[f.name] = {{"median_abs_error", f.median_abs_error}, {"max_abs_error", f.max_abs_error},
                         {"inside", f.inside}, {"counted", f.counted}};
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
