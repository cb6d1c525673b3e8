// strut bench units: identification of drawn units (study::RunUnitsStudy), none of them the model's
// defaults: coverage of the 95 % intervals, noise-floor verdicts, restarts from far off.
#include <fmt/ranges.h>

#include <iostream>
#include <nlohmann/json.hpp>

#include "bench_options.h"
#include "commands.h"
#include "option_checks.h"
#include "output_files.h"
#include "strut/ident/session_fit.h"
#include "strut/sim/draw.h"
#include "strut/study/units.h"
#include "strut/study/units_compare.h"

namespace strut::tools {
namespace {

nlohmann::json UnitJson(const study::UnitFit& unit) {
  nlohmann::json row{{"seed", unit.seed}, {"verdict", ident::ToString(unit.verdict)},
                     {"worst_noise_ratio", unit.worst_noise_ratio}};
  for (const auto& [key, z] : unit.z) row["z"][key] = z;
  for (const auto& [key, v] : unit.estimate) row["estimate"][key] = v;
  for (const auto& [key, v] : unit.sd) row["sd"][key] = v;
  if (unit.stroke_zero_sd > 0) row["stroke_zero"] = {{"value", unit.stroke_zero}, {"sd", unit.stroke_zero_sd}};
  if (unit.restarted) row["restart_apart_sd"] = unit.restart_apart_sd;
  return row;
}

// A figure's largest difference and its unit, or "-" where the two runs do not both have it.
std::string Largest(long units, double difference, unsigned long seed) {
  return units == 0 ? fmt::format("{:<20}", "-") : fmt::format("{:<9.3g} (unit {:4})", difference, seed);
}

void PrintComparison(const study::UnitsRun& before, const study::UnitsComparison& c) {
  std::cout << fmt::format("\ncompared with {}: {} units in both, tolerance {:g} relative{}; the largest relative "
                           "difference per parameter:\n",
                           before.source, c.units, c.tolerance,
                           c.before_has_estimates ? "" : " (the earlier run kept no estimates: z alone)");
  for (const study::ParameterDifference& p : c.parameters)
    std::cout << fmt::format("  {:<8} estimate {}  z {}\n", p.key, Largest(p.estimate_units, p.estimate, p.estimate_seed),
                             Largest(p.units, p.z, p.z_seed));
  if (!c.only_before.empty())
    std::cout << fmt::format("units only in the earlier run (not compared): {}\n", fmt::join(c.only_before, " "));
  if (!c.only_now.empty())
    std::cout << fmt::format("units only in this run (not compared): {}\n", fmt::join(c.only_now, " "));
  for (const std::string& m : c.missing) std::cout << "  " << m << "\n";
  std::cout << fmt::format("{} differences above the tolerance, {} figures in one run only: {}\n", c.exceeded,
                           c.missing.size(), c.same() ? "the same" : "DIFFERENT");
}

struct BenchUnits {
  study::UnitsOptions options;
  std::string calibration;  //!< the fit's calibration (--calibration of identify); empty: the lab's
  std::string json_path;
  std::string compare_path;  //!< an earlier run's --json to compare this one with
  double tolerance = 1e-9;

  void Run() {
    CheckOutputPath("--json", json_path, compare_path.empty() ? std::vector<std::string>{}
                                                              : std::vector<std::string>{compare_path});
    // Read before the units run, so that a wrong file costs no study.
    const study::UnitsRun before = compare_path.empty() ? study::UnitsRun{} : study::ReadUnitsRun(compare_path);
    if (!calibration.empty()) {
      options.gain_sd = ident::ParseGainSd(calibration);
      try {
        ident::CheckGainChannels(options.gain_sd, ident::Model::Build(options.base, ident::Causality::kStrokeInput));
      } catch (const std::invalid_argument& e) {
        throw std::invalid_argument(std::string("--calibration: ") + e.what());
      }
    }
    std::cout << study::UnitsHeading(options);
    const study::UnitsStudy s =
        study::RunUnitsStudy(options, [](const study::UnitFit& unit) { std::cout << study::UnitLine(unit); });
    std::cout << study::UnitsSummary(options, s);
    if (!json_path.empty()) WriteJson(s);
    if (compare_path.empty()) return;
    const study::UnitsComparison c = study::CompareUnits(before, study::ToRun(s), tolerance);
    PrintComparison(before, c);
    if (!c.same()) throw ExitCode(kExitDifferent);
  }

  void WriteJson(const study::UnitsStudy& s) const {
    nlohmann::json rows = nlohmann::json::array(), coverage = nlohmann::json::object();
    for (const study::UnitFit& unit : s.units) rows.push_back(UnitJson(unit));
    for (const auto& [key, c] : s.coverage)
      coverage[key] = {{"inside", c.inside}, {"total", c.total}, {"mean_z", c.mean_z}, {"sd_z", c.sd_z}};
    WriteJsonOutput(json_path, nlohmann::json{{"units", rows},
                                              {"coverage", coverage},
                                              {"pooled_inside", s.pooled_inside},
                                              {"pooled_total", s.pooled_total},
                                              {"converged", s.converged},
                                              {"at_noise_floor", s.at_floor},
                                              {"same_optimum", s.same_optimum},
                                              {"restarts", s.restarts}});
  }
};

}  // namespace

void RegisterBenchUnits(CLI::App& bench) {
  auto [sub, command] = AddCommand<BenchUnits>(
      bench, "units",
      "Identification of drawn units: coverage of the 95 % intervals, noise-floor verdicts, restarts from far off.");
  AddDrawnUnitsOptions(*sub, command->options, "The number of drawn units.", 100000);
  AddUnitsBaseOption(*sub, command->options.base,
                     "The units' physics and the fitted model: 1dof, 1dof+heat-exchange or 2dof.");
  sub->add_flag("--servo", command->options.servo, "Drive the damper through the servo actuator (default: an ideal actuator).");
  sub->add_flag("--shipped-calibration", command->options.shipped_calibration,
                "Keep the shipped transducers' zero and gain errors (default: perfect calibration).");
  sub->add_flag("--drawn-gains", command->options.drawn_gains,
                "Draw each unit's force, pressure and stroke transducer gain errors from the lab calibration "
                "(kLabGainSd: normal, sd 0.2 %, 0.2 %, 0.1 %): the coverage of intervals that hold the calibration.");
  sub->add_option("--calibration", command->calibration,
                  "The transducers' calibration the fits' intervals hold, as for identify (force=0.2%,pressure=0.2%,"
                  "stroke=0.1% or none); default: the lab's.")
      ->check([](const std::string& text) {
        try {
          ident::ParseGainSd(text);
          return std::string();
        } catch (const std::invalid_argument& e) {
          return std::string(e.what());
        }
      });
  sub->add_option("--start-off", command->options.start_off, "Largest relative offset of the restart in every parameter.")
      ->check(Between(0.0, 0.9))
      ->capture_default_str();
  sub->add_option("--effect", command->options.effects,
                  "An extra effect the units have and the fitted model lacks (repeat for several): the coverage of the "
                  "intervals widened for the misfit. Names as for `strut sim matrix --effect`.")
      ->check(CLI::IsMember(sim::ExtraEffects()));
  sub->add_option("--effects-per-unit", command->options.effects_per_unit,
                  "Each unit also draws 1 to this many further effects at random, among those that compose with the "
                  "base.")
      ->check(CLI::Range(0, 12));
  sub->add_flag("--fit-truth", command->options.fit_truth,
                "Fit each unit with its truth's composition (the base and every effect it has), the coverage of "
                "intervals of a model that holds the physics.");
  sub->add_flag("--top-out", command->options.top_out,
                "Before each fit, the top-out reference on the unit's served rig (as `strut rig run` starts), its "
                "stroke zero recorded in the unit's session as theta12's prior; prints the intervals' median sds.");
  sub->add_option("--json", command->json_path, "Also write the figures as JSON to this file.");
  sub->add_option("--compare", command->compare_path,
                  "Compare this run with an earlier one's --json file: per parameter the largest relative difference "
                  "of the estimates and of z over the units both ran; exit code 6 when one exceeds --tolerance.")
      ->check(CLI::ExistingFile);
  sub->add_option("--tolerance", command->tolerance, "The largest relative difference --compare accepts.")
      ->check(Between(0.0, 1e300))
      ->capture_default_str();
}

}  // namespace strut::tools
