// The truth a simulated rig runs, from the command line: --truth FILE, --draw SEED with --base
// and --effect, --ideal-actuator. Shared by `strut sim ...` and `strut rig serve-sim`.
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "strut/sim/truth.h"

namespace strut::tools {

struct TruthOptions {
  std::string truth_path;
  bool ideal_actuator = false;
  std::optional<std::uint64_t> draw_seed;
  std::string base = "2dof";
  std::vector<std::string> effects;
  CLI::Option* base_option = nullptr;
  CLI::Option* effect_option = nullptr;

  //! Adds the options to `command` (--ideal-actuator only `with_actuator`).
  void Add(CLI::App& command, bool with_actuator = false);
  //! The truth the options describe. Throws std::invalid_argument or sim::TruthError naming the
  //! option or file.
  sim::Truth Load() const;
};

}  // namespace strut::tools
