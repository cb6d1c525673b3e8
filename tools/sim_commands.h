// strut sim matrix and sim drop: their options and their work, apart from the printing. The CLI
// (cmd_sim.cpp) and the Python package (python/, docs/python.md) bind the same options and call the
// same Record().
#pragma once

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

#include "strut/daq/session.h"
#include "strut/sim/simulated_rig.h"
#include "truth_options.h"

namespace strut::tools {

//! --seed, --real-time, --speed.
struct RunOptions {
  unsigned long seed = 1;
  bool real_time = false;
  double speed = 1.0;

  void Add(CLI::App& command);
  sim::RigRunOptions Get() const;
};

struct SimMatrixCommand {
  TruthOptions truth;
  RunOptions run;
  std::string matrix_path;
  std::string output;
  bool force = false;

  //! Runs the matrix on the simulated rig and writes the session to --output; logs, prints nothing.
  //! `reports` (optional) receives each experiment's run report; `wall_seconds` the time it took.
  daq::Session Record(std::vector<sim::PeriodicRunReport>* reports = nullptr, double* wall_seconds = nullptr) const;
  void Run() const;
};

struct SimDropCommand {
  TruthOptions truth;
  RunOptions run;
  sim::DropSpec drop;
  std::string output;
  bool force = false;

  //! Runs the drop on the simulated rig and writes the session to --output; logs, prints nothing.
  daq::Session Record(sim::DropRunReport* report = nullptr, double* wall_seconds = nullptr) const;
  void Run() const;
};

//! Add the options of sim matrix and sim drop to `command`, bound to the command object.
void AddSimMatrixOptions(CLI::App& command, SimMatrixCommand& matrix);
void AddSimDropOptions(CLI::App& command, SimDropCommand& drop);

}  // namespace strut::tools
