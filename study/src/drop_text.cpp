// The text `strut bench drop` prints (and `strut batch` for a drop job), and a unit's record.
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <nlohmann/json.hpp>

#include "strut/study/drop.h"

namespace strut::study {

std::string DropHeading(const DropOptions& o) {
  return fmt::format("drop prediction from shaker fits of {} drawn 2dof units{} (seeds {}..): {} kg at {} m/s, {} s\n",
                     o.units, o.effects.empty() ? "" : " with " + fmt::format("{}", fmt::join(o.effects, ", ")),
                     o.first_seed, o.mass, o.velocity, o.duration);
}

std::string DropUnitLine(const DropUnit& u) {
  std::string line = fmt::format("peak force {:+.2f} % ({}), max stroke {:+.2f} % ({}), final {:+.2f} %",
                                 100 * u.peak_force_error, u.peak_force_inside ? "in" : "OUT", 100 * u.max_stroke_error,
                                 u.max_stroke_inside ? "in" : "OUT", 100 * u.final_stroke_error);
  for (const auto& [term, affects] : u.missing_physics) line += fmt::format("; {}: {}", term, affects);
  return fmt::format("  unit {:5}: {:<17} {}; prediction {:.0f} ms CPU, with intervals ({} runs) {:.0f} ms\n", u.seed,
                     ident::ToString(u.verdict), line, 1e3 * u.cpu, u.simulations, 1e3 * u.intervals_cpu);
}

std::string DropSummary(const DropOptions& o, const DropStudy& s) {
  std::string text = fmt::format("\nfits at the noise floor {}/{}; peak force and max stroke both within 5 %: {}/{}\n",
                                 s.at_floor, s.fits, s.within5, o.units);
  text += "figure               median |error|   max |error|   truth inside 95 % interval (times: error in ms)\n";
  for (const DropFigureSummary& f : s.figures)
    text += fmt::format("  {:<20} {:8.3f} {}      {:8.3f} {}    {}/{}\n", f.name, (f.time ? 1e3 : 100) * f.median_abs_error,
                        f.time ? "ms" : "% ", (f.time ? 1e3 : 100) * f.max_abs_error, f.time ? "ms" : "% ", f.inside,
                        f.counted);
  text += fmt::format(
      "a {} s drop prediction: median {:.0f} ms CPU ({:.0f} ms wall), target < 1 s; with intervals median {:.0f} ms "
      "CPU ({:.0f} ms wall)\n",
      o.duration, 1e3 * s.cpu_median, 1e3 * s.wall_median, 1e3 * s.intervals_cpu_median, 1e3 * s.intervals_wall_median);
  return text;
}

nlohmann::json DropUnitJson(const DropUnit& u) {
  nlohmann::json figures = nlohmann::json::array(), missing = nlohmann::json::array();
  for (const DropFigureError& f : u.figures)
    figures.push_back({{"name", f.name}, {"time", f.time}, {"error", f.error}, {"inside", f.inside},
                       {"has_interval", f.has_interval}});
  for (const auto& [term, affects] : u.missing_physics) missing.push_back({term, affects});
  return {{"seed", u.seed},
          {"verdict", static_cast<int>(u.verdict)},
          {"verdict_text", ident::ToString(u.verdict)},
          {"figures", figures},
          {"peak_force_error", u.peak_force_error},
          {"max_stroke_error", u.max_stroke_error},
          {"final_stroke_error", u.final_stroke_error},
          {"peak_force_inside", u.peak_force_inside},
          {"max_stroke_inside", u.max_stroke_inside},
          {"missing_physics", missing},
          {"simulations", u.simulations},
          {"timing", {{"cpu", u.cpu}, {"wall", u.wall}, {"intervals_cpu", u.intervals_cpu},
                      {"intervals_wall", u.intervals_wall}}}};
}

DropUnit DropUnitFromJson(const nlohmann::json& j) {
  DropUnit u;
  u.seed = j.at("seed").get<unsigned long>();
  u.verdict = static_cast<ident::FitVerdict>(j.at("verdict").get<int>());
  for (const nlohmann::json& f : j.at("figures"))
    u.figures.push_back({f.at("name").get<std::string>(), f.at("time").get<bool>(), f.at("error").get<double>(),
                         f.at("inside").get<bool>(), f.at("has_interval").get<bool>()});
  u.peak_force_error = j.at("peak_force_error").get<double>();
  u.max_stroke_error = j.at("max_stroke_error").get<double>();
  u.final_stroke_error = j.at("final_stroke_error").get<double>();
  u.peak_force_inside = j.at("peak_force_inside").get<bool>();
  u.max_stroke_inside = j.at("max_stroke_inside").get<bool>();
  for (const nlohmann::json& m : j.at("missing_physics"))
    u.missing_physics.emplace_back(m.at(0).get<std::string>(), m.at(1).get<std::string>());
  u.simulations = j.at("simulations").get<int>();
  const nlohmann::json& t = j.at("timing");
  u.cpu = t.at("cpu").get<double>();
  u.wall = t.at("wall").get<double>();
  u.intervals_cpu = t.at("intervals_cpu").get<double>();
  u.intervals_wall = t.at("intervals_wall").get<double>();
  return u;
}

}  // namespace strut::study
