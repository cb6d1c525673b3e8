// strut bench confusion: discovery on drawn units (sim::DrawUnit) that hold one catalogue effect at a
// drawn size, or none: how often the right term is named first, what else is added, and how often
// a unit with nothing missing gets a term anyway (false discoveries).
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "commands.h"
#include "option_checks.h"
#include "output_files.h"
#include "strut/ident/discover.h"
#include "strut/sim/draw.h"
#include "strut/sim/simulated_rig.h"

namespace strut::tools {
namespace {

struct BenchConfusion {
  int units = 10;
  unsigned long first_seed = 2000;
  std::string base = "2dof";
  std::string effects = "none,viscous-damping,stribeck-friction,oil-compressibility,real-gas,end-stop";
  bool servo = false;
  std::string json_path;

  void Run() const {
    CheckOutputPath("--json", json_path, {});
    sim::Truth around = sim::WithIdealRig(sim::DefaultTruth());
    if (servo) around.actuator.ideal = false;
    ident::SessionFitOptions fit;
    fit.composition = base;
    const ident::Model model = ident::Model::Build(base, fit.causality);
    std::vector<std::string> list;
    std::stringstream in(effects);
    for (std::string item; std::getline(in, item, ',');) list.push_back(item);
    std::cout << fmt::format("discovery from {} on drawn units ({} per row, seeds {}..), {} actuator, perfect calibration:\n",
                             base, units, first_seed, servo ? "servo" : "ideal");
    std::cout << fmt::format("  {:<20} {:>6} {:>12} {:>12} {:>10} {:>10}  {}\n", "truth holds", "units", "right first",
                             "extra terms", "none found", "median s", "what was added");
    nlohmann::json rows = nlohmann::json::array();
    for (const std::string& effect : list) {
      sim::UnitDraw draw;
      draw.base = base;
      if (effect != "none") draw.effects.push_back({effect, std::nullopt});
      int right = 0, extra = 0, none = 0;
      std::vector<double> seconds;
      std::map<std::string, int> added;
      for (int u = 0; u < units; ++u) {
        const unsigned long seed = first_seed + u;
        const sim::SimulatedRig rig(sim::DrawUnit(around, draw, seed));
        sim::RigRunOptions run;
        run.seed = seed;
        const daq::Session session = rig.RunMatrix(sim::StandardMatrixPlan(), run);
        const auto start = std::chrono::steady_clock::now();
        const ident::DiscoveryResult r =
            ident::Discover(ident::PrepareFitData(session, fmt::format("unit {}", seed), model, fit.estimator.n), fit, {});
        seconds.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
        if (r.missing.empty()) ++none;
        if (effect != "none" && !r.missing.empty() && r.missing.front() == effect) ++right;
        const std::size_t expected = effect == "none" ? 0 : 1;
        if (r.missing.size() > expected || (effect != "none" && !r.missing.empty() && r.missing.front() != effect)) ++extra;
        std::string names;
        for (const auto& t : r.missing) names += (names.empty() ? "" : "+") + t;
        ++added[names.empty() ? "(nothing)" : names];
      }
      std::sort(seconds.begin(), seconds.end());
      std::string what;
      for (const auto& [names, count] : added) what += fmt::format("{}{} x{}", what.empty() ? "" : ", ", names, count);
      std::cout << fmt::format("  {:<20} {:>6} {:>12} {:>12} {:>10} {:>10.2f}  {}\n", effect, units,
                               effect == "none" ? std::string("-") : std::to_string(right), extra, none,
                               seconds[seconds.size() / 2], what);
      rows.push_back({{"effect", effect}, {"units", units}, {"right_first", right}, {"extra", extra},
                      {"nothing_found", none}, {"median_seconds", seconds[seconds.size() / 2]}, {"added", added}});
    }
    if (!json_path.empty()) WriteTextOutput(json_path, nlohmann::json{{"confusion", rows}}.dump(1) + "\n");
  }
};

}  // namespace

void RegisterBenchConfusion(CLI::App& bench) {
  auto command = std::make_shared<BenchConfusion>();
  CLI::App* sub = bench.add_subcommand(
      "confusion", "Discovery on drawn units with one catalogue effect or none: right first terms, extras, false discoveries.");
  sub->add_option("--units", command->units, "Drawn units per effect.")->check(Between(1, 10000))->capture_default_str();
  sub->add_option("--first-seed", command->first_seed, "Seed of the first unit.")->capture_default_str();
  sub->add_option("--base", command->base, "The units' base physics and the baseline model: 1dof, 1dof+heat-exchange or 2dof.")
      ->check(CLI::IsMember({"1dof", "1dof+heat-exchange", "2dof"}))
      ->capture_default_str();
  sub->add_option("--effects", command->effects, "The effects, separated by commas; 'none' stands for units with nothing missing.")
      ->capture_default_str();
  sub->add_flag("--servo", command->servo, "Drive the damper through the servo actuator (default: an ideal actuator).");
  sub->add_option("--json", command->json_path, "Also write the table as JSON to this file.");
  sub->callback([command] { command->Run(); });
}

}  // namespace strut::tools
