// strut bench stroke-zero: the top-out reference on drawn units (study::ReferenceDrawnUnit): the
// stroke zero found against the truth, its sd and the coverage of its interval.
#include <unistd.h>

#include <fmt/format.h>

#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>

#include "bench_options.h"
#include "commands.h"
#include "option_checks.h"
#include "output_files.h"
#include "strut/study/stroke_zero.h"

namespace strut::tools {
namespace {

struct BenchStrokeZero {
  study::StrokeZeroOptions options;
  std::string json_path;
  bool ideal_actuator = false, calibrated = false;

  void Run() {
    options.draw.servo = !ideal_actuator;
    options.draw.shipped_calibration = !calibrated;
    CheckOutputPath("--json", json_path, {});
    options.scratch = (std::filesystem::temp_directory_path() / fmt::format("strut-stroke-zero-{}.h5", ::getpid())).string();
    std::vector<study::StrokeZeroUnit> units;
    for (int u = 0; u < options.draw.units; ++u) {
      units.push_back(study::ReferenceDrawnUnit(options, u));
      std::cout << study::StrokeZeroLine(units.back()) << "\n" << std::flush;
    }
    const study::StrokeZeroStudy s = study::SummariseStrokeZero(std::move(units));
    std::cout << study::StrokeZeroSummary(options, s);
    if (json_path.empty()) return;
    nlohmann::json rows = nlohmann::json::array();
    for (const study::StrokeZeroUnit& u : s.units)
      rows.push_back({{"seed", u.seed}, {"theta12", u.theta12}, {"truth", u.truth}, {"found", u.found},
                      {"zero", u.zero}, {"sd", u.sd}, {"fit_sd", u.fit_sd}, {"stiffness", u.stiffness},
                      {"failure", u.failure}, {"wall", u.wall}});
    WriteJsonOutput(json_path, nlohmann::json{{"units", rows},
                                              {"found", s.found},
                                              {"mean_error", s.mean_error},
                                              {"sd_error", s.sd_error},
                                              {"largest_error", s.largest_error},
                                              {"median_sd", s.median_sd},
                                              {"within_1sd", s.within_1sd},
                                              {"within_1.96sd", s.within_2sd}});
  }
};

}  // namespace

void RegisterBenchStrokeZero(CLI::App& bench) {
  auto [sub, command] = AddCommand<BenchStrokeZero>(
      bench, "stroke-zero",
      "The top-out reference on drawn units, served in this process through the real drivers: the stroke zero it "
      "finds against the truth the unit's LVDT reads at full extension, its sd and the coverage of its interval.");
  study::StrokeZeroOptions& o = command->options;
  o.draw.units = 50;
  AddDrawnUnitsOptions(*sub, o.draw, "The number of drawn units (the units of `strut bench units` with these seeds).",
                       100000);
  AddUnitsBaseOption(*sub, o.draw.base, "The units' physics: 1dof, 1dof+heat-exchange or 2dof.");
  sub->add_flag("--ideal-actuator", command->ideal_actuator, "An ideal actuator instead of the servo actuator.");
  sub->add_flag("--calibrated", command->calibrated,
                "Perfect transducers instead of the shipped ones (their zero and gain errors).");
  sub->add_option("--speed", o.speed, "Simulated seconds per wall second of the served rig.")
      ->check(Between(1.0, 1000.0))
      ->capture_default_str();
  sub->add_option("--top-out-rate", o.top_out.rate, "Rate of the search, m/s.")
      ->check(Between(1e-6, 0.01, "m/s"))
      ->capture_default_str();
  sub->add_option("--top-out-force", o.top_out.force_drop, "The search's force limit below the trend, N.")
      ->check(Between(10.0, 2.0e4, "N"))
      ->capture_default_str();
  sub->add_option("--json", command->json_path, "Also write the figures as JSON to this file.");
}

}  // namespace strut::tools
