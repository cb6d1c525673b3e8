// strut bench dropfit: what one drop adds to a shaker fit (issue 15, docs/drop-prediction.md "Drop
// records in the fit"; study::RunDropFitStudy): theta3's sd alone and with the drop, interval
// coverage, and the drop predicted from each fit against the truth's.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "bench_options.h"
#include "option_checks.h"
#include "output_files.h"
#include "strut/study/drop_fit.h"

namespace strut::tools {
namespace {

nlohmann::json FiguresJson(const study::DropFitFigures& f) {
  return {{"verdict", f.verdict},
          {"theta3", f.theta3},
          {"theta3_sd", f.theta3_sd},
          {"theta3_z", f.z},
          {"inside_95", f.inside},
          {"estimated", f.estimated},
          {"max_stroke_error", f.max_stroke_error},
          {"max_stroke_inside", f.max_stroke_inside},
          {"peak_force_error", f.peak_force_error},
          {"fit_cpu_s", f.cpu},
          {"max_stroke_error_terms", f.max_stroke_terms}};
}

void PrintUnit(const study::DropFitUnit& u) {
  const study::DropFitFigures &a = u.alone, &b = u.with_drop;
  std::cout << fmt::format("  {:5}  {:8.1f} +- {:5.1f} ({:+.2f})          {:8.1f} +- {:5.2f} ({:+.2f})      {:6.1f}"
                           "    {:2}/{:2} {:2}/{:2}  {:+.2f} % / {:+.2f} %{}\n",
                           u.seed, a.theta3, a.theta3_sd, a.z, b.theta3, b.theta3_sd, b.z, u.theta3_sd_ratio, a.inside,
                           a.estimated, b.inside, b.estimated, 100 * a.max_stroke_error, 100 * b.max_stroke_error,
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
  std::cout << fmt::format("         the shaker fit's max stroke error from its estimates' errors: {}{}\n", largest_terms,
                           zero == a.z_of.end() ? "" : fmt::format("; stroke zero theta12 z {:+.2f}", zero->second));
}

struct BenchDropFit {
  study::DropFitOptions options;
  std::string json_path;

  void Run() const {
    CheckOutputPath("--json", json_path, {});
    const int units = options.units;
    std::cout << fmt::format("theta3 from the shaker matrix alone and with one drop ({} kg at {} m/s, {} s) of {} drawn "
                             "2dof units on the ideal rig (seeds {}..)\n",
                             options.mass, options.velocity, options.duration, units, options.first_seed);
    std::cout << "  unit   shaker alone: theta3 +- sd (z)      with the drop: theta3 +- sd (z)    sd ratio  "
                 "in 95 %  max stroke error (alone / with)\n";
    const study::DropFitStudy s = study::RunDropFitStudy(options, PrintUnit);
    const study::DropFitSide &a = s.alone, &b = s.with_drop;
    std::cout << fmt::format(
        "\ntheta3 sd, shaker alone over shaker and drop: median {:.1f}, range {:.1f} .. {:.1f}\n"
        "truth inside the 95 % interval of theta3: alone {}/{}, with the drop {}/{}; of every estimated parameter: "
        "alone {}/{}, with the drop {}/{}\n"
        "fits at the noise floor: alone {}/{}, with the drop {}/{}\n"
        "max stroke of the predicted drop: median error alone {:+.2f} % (largest {:.2f} %, under-predicted on {}/{}, "
        "truth inside the interval {}/{}); with the drop {:+.2f} % (largest {:.2f} %, under-predicted on {}/{}, inside "
        "{}/{})\n"
        "fit time (CPU of one thread): median alone {:.1f} s, with the drop {:.1f} s\n",
        s.ratio_median, s.ratio_min, s.ratio_max, a.theta3_inside, units, b.theta3_inside, units, a.inside, a.estimated,
        b.inside, b.estimated, a.at_floor, units, b.at_floor, units, 100 * a.max_stroke_error_median,
        100 * a.max_stroke_error_largest, a.max_stroke_under, units, a.max_stroke_inside, units,
        100 * b.max_stroke_error_median, 100 * b.max_stroke_error_largest, b.max_stroke_under, units,
        b.max_stroke_inside, units, a.cpu_median, b.cpu_median);
    const auto median_z = [&](const std::string& key) {
      const auto z = s.alone_median_z.find(key);
      return z == s.alone_median_z.end() ? NAN : z->second;
    };
    std::string split;
    for (std::size_t k = 0; k < std::min<std::size_t>(4, s.alone_terms.size()); ++k)
      split += fmt::format("{}{} {:+.2f} % (median z {:+.2f})", k ? ", " : "", s.alone_terms[k].second,
                           100 * s.alone_terms[k].first, median_z(s.alone_terms[k].second));
    std::cout << fmt::format("shaker alone's max stroke error, linearised over its estimates' errors (median per "
                             "parameter): {}; the stroke zero theta12: median z {:+.2f}\n",
                             split, median_z("theta12"));
    if (json_path.empty()) return;
    nlohmann::json rows = nlohmann::json::array();
    for (const study::DropFitUnit& u : s.units)
      rows.push_back({{"seed", u.seed},
                      {"theta3_truth", u.theta3_truth},
                      {"shaker", FiguresJson(u.alone)},
                      {"shaker_and_drop", FiguresJson(u.with_drop)},
                      {"theta3_sd_ratio", u.theta3_sd_ratio}});
    WriteJsonOutput(json_path, nlohmann::json{{"units", rows},
                                              {"theta3_sd_ratio_median", s.ratio_median},
                                              {"theta3_sd_ratio_min", s.ratio_min},
                                              {"theta3_sd_ratio_max", s.ratio_max},
                                              {"theta3_inside_alone", a.theta3_inside},
                                              {"theta3_inside_with_drop", b.theta3_inside},
                                              {"inside_alone", a.inside},
                                              {"inside_with_drop", b.inside},
                                              {"estimated_alone", a.estimated},
                                              {"estimated_with_drop", b.estimated}});
  }
};

}  // namespace

void RegisterBenchDropFit(CLI::App& bench) {
  auto [sub, command] = AddCommand<BenchDropFit>(
      bench, "dropfit",
      "What one drop adds to a shaker fit on drawn units: theta3's sd alone and with the drop, interval "
      "coverage, and the drop predicted from each fit.");
  AddDropBenchOptions(*sub, command->options, "Seconds of the drop record from contact.");
  sub->add_option("--json", command->json_path, "Also write the figures as JSON to this file.");
}

}  // namespace strut::tools
