// strut bench confusion: discovery on drawn units (study::RunConfusionStudy) that hold one catalogue
// effect at a drawn size, or none: how often the right term is named first, what else is added, and
// how often a unit with nothing missing gets a term anyway (false discoveries).
#include <fmt/format.h>

#include <cmath>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "bench_options.h"
#include "commands.h"
#include "option_checks.h"
#include "output_files.h"
#include "strut/study/confusion.h"

namespace strut::tools {
namespace {

struct BenchConfusion {
  study::ConfusionOptions options;
  std::string effects = "none,viscous-damping,stribeck-friction,oil-compressibility,real-gas,end-stop";
  std::string sizes = "drawn";
  std::string json_path;
  std::string sessions_dir;

  void Run() {
    CheckOutputPath("--json", json_path, {});
    options.effects.clear();
    std::stringstream in(effects);
    for (std::string item; std::getline(in, item, ',');) options.effects.push_back(item);
    options.study_sizes = sizes == "study";
    study::CheckConfusionEffects(options);
    std::cout << study::ConfusionHeading(options);
    nlohmann::json unit_rows = nlohmann::json::array();
    const auto on_unit = [&](const study::ConfusionUnit& unit, const daq::Session& session) {
      if (!sessions_dir.empty()) {
        // Kept so that a unit can be looked at again: strut -v discover DIR/EFFECT-SEED.h5 --model BASE.
        const std::string path = fmt::format("{}/{}-{}.h5", sessions_dir, unit.effect, unit.seed);
        CheckOutputPath("--sessions", path, {});
        daq::WriteSession(path, session);
      }
      const nlohmann::json row = study::ConfusionUnitJson(unit);
      // A line per unit as it ends, so a long study that is stopped keeps what it measured.
      std::cout << "unit " << row.dump() << std::endl;
      unit_rows.push_back(row);
    };
    nlohmann::json rows = nlohmann::json::array();
    std::vector<study::ConfusionRow> done;
    for (const std::string& effect : options.effects) {
      study::ConfusionOptions one = options;  // one effect at a time: its row is printed as it ends
      one.effects = {effect};
      done.push_back(study::RunConfusionStudy(one, on_unit).front());
      std::cout << study::ConfusionRowLine(done.back());
      rows.push_back(study::ConfusionRowJson(done.back()));
    }
    std::cout << study::ConfusionDetection(done);
    if (!json_path.empty())
      WriteJsonOutput(json_path, nlohmann::json{{"confusion", rows}, {"sizes", sizes}, {"units", unit_rows}});
  }
};

}  // namespace

void RegisterBenchConfusion(CLI::App& bench) {
  auto [sub, command] = AddCommand<BenchConfusion>(
      bench, "confusion",
      "Discovery on drawn units with one catalogue effect or none: right first terms, extras, false discoveries.");
  AddDrawnUnitsOptions(*sub, command->options, "Drawn units per effect.", 10000, "Seed of the first unit.");
  AddUnitsBaseOption(*sub, command->options.base,
                     "The units' base physics and the baseline model: 1dof, 1dof+heat-exchange or 2dof.");
  sub->add_option("--effects", command->effects, "The effects, separated by commas; 'none' stands for units with nothing missing; 'gas-solubility' "
                  "(with --base 1dof+heat-exchange) for units drawn as 2dof, which holds it.")
      ->capture_default_str();
  sub->add_flag("--servo", command->options.servo, "Drive the damper through the servo actuator (default: an ideal actuator).");
  sub->add_flag("--shipped-calibration", command->options.shipped_calibration,
                "Keep the shipped transducers' zero and gain errors (default: perfect calibration).");
  sub->add_flag("--decide", command->options.decide,
                "Where discovery names explanations that fit alike, run the test that decides on the unit's simulated "
                "rig and count the decisions that chose the truth (docs/discovery.md).");
  sub->add_flag("--leave-out", command->options.leave_out,
                "Leave-one-out: leave each unit's effect out of the catalogue discovery may name, so that only the "
                "empirical discrepancy can take it up; the table adds the units at the noise floor, those that used "
                "the discrepancy, and those it described as the effect (docs/discovery.md).");
  sub->add_option("--sizes", command->sizes,
                  "How the effects' sizes are drawn: 'drawn' (the simulated rig's realistic spreads) or 'study' (from "
                  "barely detectable to plain, docs/discovery.md), which also prints the detection size.")
      ->check(CLI::IsMember({"drawn", "study"}))
      ->capture_default_str();
  sub->add_option("--json", command->json_path, "Also write the table and every unit's result as JSON to this file.");
  sub->add_option("--sessions", command->sessions_dir,
                  "Also write every unit's session to this existing folder as EFFECT-SEED.h5 (an existing session is "
                  "refused), to run strut discover on it again.")
      ->check(CLI::ExistingDirectory);
}

}  // namespace strut::tools
