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

nlohmann::json UnitJson(const study::ConfusionUnit& unit) {
  nlohmann::json row{{"effect", unit.effect}, {"seed", unit.seed}, {"found", unit.found},
                     {"right_first", unit.right_first}, {"seconds", unit.seconds}};
  if (const auto& s = unit.signal)
    row["signal"] = {{"rms", s->rms},           {"experiment", s->experiment},
                     {"channel", s->channel},   {"chi2", s->chi2},
                     {"left_rms", s->left_rms}, {"left_experiment", s->left_experiment},
                     {"left_channel", s->left_channel}};
  if (unit.size) row["size"] = *unit.size;
  if (const auto& f = unit.first_round)
    row["first_round"] = {{"delta_bic", f->delta_bic}, {"cv_ratio", f->cv_ratio}, {"verdict", f->verdict}};
  return row;
}

//! The detection sizes of an effect and its units in five bins by their signal.
std::string DetectionLines(const study::ConfusionRow& row) {
  const auto shown = [](double x, std::string_view unit) {
    return std::isfinite(x) ? fmt::format("{:.3g} {}", x, unit) : std::string("not reached");
  };
  std::string line = fmt::format("  {}: detection (>= 95 % right first above it) in the signal {}, in the signal "
                                 "left after the baseline {}",
                                 row.effect, shown(row.detection_signal, "sd"), shown(row.detection_left, "sd"));
  if (const study::StudyRange* r = row.study)
    line += fmt::format(", in theta{} ({} {:.3g}..{:.3g} {}) {}", r->index, r->log ? "log-uniform" : "uniform", r->low,
                        r->high, r->unit, shown(row.detection_size, r->unit));
  line += "\n";
  for (const study::MeasureBin& b : row.by_signal)
    line += fmt::format("    {:.3g}..{:.3g} {}: right first {}/{}\n", b.low, b.high, "sd", b.right, b.count);
  return line;
}

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
    for (const std::string& effect : options.effects)
      if (options.study_sizes && effect != "none" && !study::FindStudyRange(effect))
        throw std::invalid_argument(fmt::format("--effects: no study range for '{}'", effect));
    std::cout << fmt::format("discovery from {} on drawn units ({} per row, seeds {}..), {} actuator, {} calibration:\n",
                             options.base, options.units, options.first_seed, options.servo ? "servo" : "ideal",
                             options.shipped_calibration ? "shipped" : "perfect");
    std::cout << fmt::format("  {:<20} {:>6} {:>12} {:>12} {:>10} {:>10}  {}\n", "truth holds", "units", "right first",
                             "extra terms", "none found", "median s", "what was added");
    nlohmann::json unit_rows = nlohmann::json::array();
    const auto on_unit = [&](const study::ConfusionUnit& unit, const daq::Session& session) {
      if (!sessions_dir.empty()) {
        // Kept so that a unit can be looked at again: strut -v discover DIR/EFFECT-SEED.h5 --model BASE.
        const std::string path = fmt::format("{}/{}-{}.h5", sessions_dir, unit.effect, unit.seed);
        CheckOutputPath("--sessions", path, {});
        daq::WriteSession(path, session);
      }
      const nlohmann::json row = UnitJson(unit);
      // A line per unit as it ends, so a long study that is stopped keeps what it measured.
      std::cout << "unit " << row.dump() << std::endl;
      unit_rows.push_back(row);
    };
    nlohmann::json rows = nlohmann::json::array();
    std::string detection;
    for (const std::string& effect : options.effects) {
      study::ConfusionOptions one = options;  // one effect at a time: its row is printed as it ends
      one.effects = {effect};
      const study::ConfusionRow row = study::RunConfusionStudy(one, on_unit).front();
      if (effect != "none") detection += DetectionLines(row);
      std::string what;
      for (const auto& [names, count] : row.added) what += fmt::format("{}{} x{}", what.empty() ? "" : ", ", names, count);
      std::cout << fmt::format("  {:<20} {:>6} {:>12} {:>12} {:>10} {:>10.2f}  {}\n", effect, row.units,
                               effect == "none" ? std::string("-") : std::to_string(row.right), row.extra, row.none,
                               row.median_seconds, what);
      nlohmann::json j{{"effect", effect},          {"units", row.units},
                       {"right_first", row.right},  {"extra", row.extra},
                       {"nothing_found", row.none}, {"median_seconds", row.median_seconds},
                       {"added", row.added}};
      if (std::isfinite(row.detection_signal)) j["detection_signal"] = row.detection_signal;
      if (std::isfinite(row.detection_left)) j["detection_left"] = row.detection_left;
      if (std::isfinite(row.detection_size)) j["detection_size"] = row.detection_size;
      rows.push_back(j);
    }
    if (!detection.empty())
      std::cout << "detection (signal: the effect's largest RMS over the noise sd in one experiment and channel; "
                   "left: what the baseline's linearised refit leaves of it; units sorted by the signal in five bins):\n"
                << detection;
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
  sub->add_option("--effects", command->effects, "The effects, separated by commas; 'none' stands for units with nothing missing.")
      ->capture_default_str();
  sub->add_flag("--servo", command->options.servo, "Drive the damper through the servo actuator (default: an ideal actuator).");
  sub->add_flag("--shipped-calibration", command->options.shipped_calibration,
                "Keep the shipped transducers' zero and gain errors (default: perfect calibration).");
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
