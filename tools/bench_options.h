// Options the bench studies of drawn units share: which units are drawn (study::UnitsOptions,
// QcOptions, ConfusionOptions, DropOptions, DropFitOptions), their base physics, and the drop
// `strut bench drop` and `strut bench dropfit` predict or record.
#pragma once

#include <CLI/CLI.hpp>
#include <string>

#include "option_checks.h"

namespace strut::tools {

//! --units (1 .. `max_units`, said by `units_help`) and --first-seed (said by `seed_help`) into `o`.
template <typename Options>
void AddDrawnUnitsOptions(CLI::App& sub, Options& o, const std::string& units_help, double max_units,
                          const std::string& seed_help = "Seed of the first unit (the others follow).") {
  sub.add_option("--units", o.units, units_help)->check(Between(1, max_units))->capture_default_str();
  sub.add_option("--first-seed", o.first_seed, seed_help)->capture_default_str();
}

//! --base (said by `help`) into `base`: the physics the units are drawn with, which is also the model fitted.
inline void AddUnitsBaseOption(CLI::App& sub, std::string& base, const std::string& help) {
  sub.add_option("--base", base, help)->check(CLI::IsMember({"1dof", "1dof+heat-exchange", "2dof"}))->capture_default_str();
}

//! --units, --first-seed, --mass, --velocity and --duration (said by `duration_help`) into `o`.
template <typename Options>
void AddDropBenchOptions(CLI::App& sub, Options& o, const std::string& duration_help) {
  AddDrawnUnitsOptions(sub, o, "Number of drawn units.", 10000);
  sub.add_option("--mass", o.mass, "Dropped mass, kg.")->check(Positive("kg"))->capture_default_str();
  sub.add_option("--velocity", o.velocity, "Stroke velocity at contact, m/s.")->check(NonNegative())->capture_default_str();
  sub.add_option("--duration", o.duration, duration_help)->check(Between(0.1, 3600.0))->capture_default_str();
}

}  // namespace strut::tools
