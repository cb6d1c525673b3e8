// The text `strut bench units` prints (and `strut batch` for a units job): heading, unit lines, summary.
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <cmath>
#include <map>
#include <vector>

#include "strut/study/statistics.h"
#include "strut/study/units.h"

namespace strut::study {

std::string UnitsHeading(const UnitsOptions& options) {
  const std::string calibrated = ident::GainSdText(options.gain_sd);
  std::string text = fmt::format(
      "identification of {} drawn {} units (seeds {}..), {} actuator, {} transducers, stroke "
      "input, default choices; the intervals hold the calibration {}:\n",
      options.units, options.base, options.first_seed, options.servo ? "servo" : "ideal",
      options.shipped_calibration ? "shipped"
      : options.drawn_gains       ? "drawn force, pressure and stroke gain"
                                  : "perfect",
      calibrated.empty() ? "none" : calibrated);
  if (options.fit_truth)
    text += "each unit is fitted with its truth's composition\n";
  else if (!options.effects.empty())
    text += fmt::format("the units also have {}, which the fitted model {} lacks: the fits stay above the noise "
                        "floor and the coverage is that of the widened intervals\n",
                        fmt::join(options.effects, " and "), options.base);
  if (options.effects_per_unit > 0)
    text += fmt::format("each unit draws 1 to {} further effects at random{}\n", options.effects_per_unit,
                        options.fit_truth ? "" : ", which the fitted model lacks");
  return text;
}

std::string UnitLine(const UnitFit& unit) {
  std::string line;
  for (const auto& [key, z] : unit.z)
    if (std::abs(z) > 3) line += fmt::format(" {} {:+.1f}", key, z);
  if (unit.restarted && !unit.same_optimum)
    line += fmt::format(" restart {} after {} iterations: {:.3g} sd apart{}",
                        unit.restart_converged ? "converged" : "NOT converged", unit.restart_iterations,
                        unit.restart_apart_sd, unit.restart_warning.empty() ? "" : " (" + unit.restart_warning + ")");
  return fmt::format("  unit {:5}: {:<18} worst noise ratio {:5.2f}, {:.2f} s{}{}\n", unit.seed,
                     ident::ToString(unit.verdict), unit.worst_noise_ratio, unit.seconds,
                     unit.truth_composition.find('+') != std::string::npos ? " (" + unit.truth_composition + ")" : "",
                     line.empty() ? "" : ";" + line);
}

std::string UnitsSummary(const UnitsOptions& o, const UnitsStudy& s) {
  std::string text = "\n95 % intervals holding the truth (Wilson 95 % range), z = (estimate - truth) / sd:\n";
  for (const auto& [key, c] : s.coverage)
    text += fmt::format("  {:<8} {:3}/{:3} = {:.3f} ({:.3f}-{:.3f})  mean z {:+.2f}  sd z {:.2f}\n", key, c.inside,
                        c.total, c.fraction(), c.wilson95.first, c.wilson95.second, c.mean_z, c.sd_z);
  const auto [lo, hi] = Wilson(s.pooled_inside, s.pooled_total);
  text += fmt::format(
      "  pooled   {}/{} = {:.3f} ({:.3f}-{:.3f}); target 0.90-0.98\n"
      "converged {}/{}; at the noise floor (no channel's pooled ratio above noise at p = {}) {}/{}; worst ratio median {:.3f}, "
      "max {:.3f}\nfrom {:.0f} % off: the same optimum in {}/{}; fit (read to verdict) median {:.3f} s wall\n"
      "CPU medians on one thread: the whole entry point (prepare, plan, fit) {:.0f} ms; the fit from the data's "
      "starting values alone {:.0f} ms (target < 100 ms); the same fit without the calibration {:.0f} ms, unit by "
      "unit {:.3f} times that (median)\n",
      s.pooled_inside, s.pooled_total, double(s.pooled_inside) / s.pooled_total, lo, hi, s.converged, o.units,
      ident::kNoiseFloorFalseAlarm, s.at_floor, o.units, s.worst_ratio_median, s.worst_ratio_max, 100 * o.start_off,
      s.same_optimum, s.restarts, s.seconds_median, 1e3 * s.cpu_median, 1e3 * s.estimator_cpu_median,
      1e3 * s.uncalibrated_cpu_median, s.cost_ratio_median);
  if (o.top_out) {
    // What the reference's zero does to the intervals: their median sd per parameter.
    std::map<std::string, std::vector<double>> sds;
    std::vector<double> zero_sds;
    long recorded = 0;
    for (const UnitFit& u : s.units) {
      for (const auto& [key, sd] : u.sd) sds[key].push_back(sd);
      if (u.stroke_zero_sd > 0) ++recorded, zero_sds.push_back(u.stroke_zero_sd);
    }
    text += fmt::format("top-out reference: a stroke zero recorded for {}/{} units, its sd median {:.2f} um; median "
                        "interval sd:",
                        recorded, s.units.size(), zero_sds.empty() ? 0.0 : 1e6 * Median(zero_sds));
    for (const auto& [key, v] : sds) text += fmt::format(" {} {:.3g}", key, Median(v));
    text += "\n";
  }
  return text;
}

}  // namespace strut::study
