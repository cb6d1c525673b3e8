// Sessions simulated directly from periodic equilibrium states: whole steady-state periods of a
// stroke-driven model plus sensor noise, written like a rig would (gauge pressure, SI units).
// The fast path for identification tests; the simulated rig builds on the same pieces.
#pragma once

#include <random>
#include <span>
#include <string>
#include <vector>

#include "strut/daq/session.h"
#include "strut/ident/model.h"
#include "strut/rig/test_matrix.h"

namespace strut::sim {

//! Standard deviations of white sensor noise (damper-physics.md §1.7).
struct SensorNoise {
  double stroke = 3e-5;     //!< m (LVDT, 0.03 mm)
  double force = 20.0;      //!< N (load cell)
  double pressure = 2.0e3;  //!< Pa (transducer)
};

struct PeriodicSessionOptions {
  double sample_rate = 200.0;  //!< Hz; must give whole samples per period for every frequency
  long periods = 3;            //!< steady-state periods recorded per experiment
  SensorNoise noise;
  unsigned seed = 1;
  bool gauge_pressure = true;  //!< record gauge pressure as most transducers do
  std::string damper_serial = "SIM-0001";
  std::string rig = "strut simulated damper (periodic steady state)";
};

//! Simulates every matrix entry with the stroke-driven `composition` model at `theta` (central4 on
//! one grid point per sample), starts each record at a random phase and adds noise.
//! Throws std::invalid_argument when a frequency does not give whole samples per period.
daq::Session SimulatePeriodicSession(const std::string& composition, std::span<const double> theta,
                                     const std::vector<rig::MatrixEntry>& matrix, const PeriodicSessionOptions& options);

//! Adds white noise of `noise` to the stroke, force and pressure channels of every experiment
//! (other channels unchanged), a standard normal draw from `rng` per sample in channel order.
void AddSensorNoise(daq::Session& session, const SensorNoise& noise, std::mt19937_64& rng);

}  // namespace strut::sim
