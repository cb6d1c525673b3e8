// The truth options of the simulated-rig commands (truth_options.h).
#include "truth_options.h"

#include <spdlog/fmt/fmt.h>

#include <stdexcept>

#include "strut/sim/draw.h"

namespace strut::tools {

void TruthOptions::Add(CLI::App& command, bool with_actuator) {
  command.add_option("--truth", truth_path, "Read the truth the rig simulates from this TOML file (default: the built-in F-16-nose-like lab damper; docs/simulated-rig.md).")
      ->check(CLI::ExistingFile);
  if (with_actuator)
    command.add_flag("--ideal-actuator", ideal_actuator, "Use an ideal actuator: the stroke follows the set-point exactly (no servo loop).");
  command.add_option("--draw", draw_seed,
                     "Simulate a unit drawn with realistic scatter around the truth (the --truth file or the "
                     "built-in one) from this seed; the same seed gives the same unit (docs/simulated-rig.md, "
                     "Drawn units).");
  base_option = command.add_option("--base", base,
                                   "With --draw: the base physics of the unit, 1dof (polytropic gas), "
                                   "1dof+heat-exchange or 2dof (heat exchange and gas solubility).")
                    ->check(CLI::IsMember({"1dof", "1dof+heat-exchange", "2dof"}))
                    ->capture_default_str();
  effect_option = command.add_option("--effect", effects,
                                     "With --draw: an extra effect the unit has, NAME or NAME=SIZE (the value of "
                                     "its sizing parameter, SI; without it the size is drawn): " +
                                         fmt::format("{}", fmt::join(sim::ExtraEffects(), ", ")) +
                                         ". Repeat the option for several effects.");
}

sim::Truth TruthOptions::Load() const {
  if (!draw_seed && (base_option->count() > 0 || effect_option->count() > 0))
    throw std::invalid_argument("--base and --effect describe a drawn unit and need --draw SEED");
  sim::Truth truth = truth_path.empty() ? sim::DefaultTruth() : sim::ReadTruthFile(truth_path);
  if (draw_seed) {
    sim::UnitDraw spec;
    spec.base = base;
    for (const std::string& item : effects) {
      const auto eq = item.find('=');
      sim::EffectRequest request{item.substr(0, eq), std::nullopt};
      if (eq != std::string::npos) {
        const std::string value = item.substr(eq + 1);
        try {
          std::size_t used = 0;
          request.size = std::stod(value, &used);
          if (used != value.size()) throw std::invalid_argument(value);
        } catch (const std::exception&) {
          throw std::invalid_argument(
              fmt::format("--effect {}: the size '{}' is not a number (NAME=SIZE, SI units)", item, value));
        }
      }
      spec.effects.push_back(request);
    }
    truth = sim::DrawUnit(truth, spec, *draw_seed);
  }
  if (ideal_actuator) truth.actuator.ideal = true;
  return truth;
}

}  // namespace strut::tools
