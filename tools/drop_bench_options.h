// The options `strut bench drop` and `strut bench dropfit` share: the drawn units and the drop
// each of them is predicted or recorded with (study::DropOptions, study::DropFitOptions).
#pragma once

#include <CLI/CLI.hpp>
#include <string>

#include "option_checks.h"

namespace strut::tools {

//! --units, --first-seed, --mass, --velocity and --duration (said by `duration_help`) into `o`.
template <typename Options>
void AddDropBenchOptions(CLI::App& sub, Options& o, const std::string& duration_help) {
  sub.add_option("--units", o.units, "Number of drawn units.")->check(Between(1, 10000))->capture_default_str();
  sub.add_option("--first-seed", o.first_seed, "Seed of the first unit (the others follow).")->capture_default_str();
  sub.add_option("--mass", o.mass, "Dropped mass, kg.")->check(Positive("kg"))->capture_default_str();
  sub.add_option("--velocity", o.velocity, "Stroke velocity at contact, m/s.")->check(NonNegative())->capture_default_str();
  sub.add_option("--duration", o.duration, duration_help)->check(Between(0.1, 3600.0))->capture_default_str();
}

}  // namespace strut::tools
