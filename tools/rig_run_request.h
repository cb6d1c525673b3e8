// A matrix run on a rig as `strut rig run` does it (cmd_rig_run.cpp), for commands that record a
// test of their own: `strut discover --decide` runs the test that decides.
#pragma once

#include <optional>
#include <string>

#include "truth_options.h"

namespace strut::tools {

struct RigRunRequest {
  std::string rig_spec;  //!< "sim", or the controller's modbus-tcp://HOST:PORT
  std::string daq_spec;  //!< the acquisition (udp:HOST:PORT, can:IFACE); "" with --rig sim
  std::string matrix_path, limits_path, output;
  bool force = false, no_progress = false;
  std::optional<double> speed;
  const TruthOptions* truth = nullptr;  //!< a simulated rig's truth (its options must be on a parsed command)
};

//! Checks, connects, runs and records the matrix as `strut rig run` does, printing its outcome;
//! throws ExitCode (4 paused, 5 stopped) when the run did not complete, as that command exits.
void RunMatrixOnRig(const RigRunRequest& request);

}  // namespace strut::tools
