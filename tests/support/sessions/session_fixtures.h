// Recorded sessions made by the simulator, the independent reference the fit is checked against:
// one set of fixtures for every test that needs a session of known truth (strut_test_sessions,
// on strut_sim).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "strut/daq/session.h"
#include "strut/ident/parameters.h"
#include "strut/ident/session_fit.h"
#include "strut/rig/test_matrix.h"
#include "strut/sim/truth.h"

namespace strut::test {

//! The standard matrix's experiments whose labels are in `labels` (e.g. "bcghkl"), in matrix order.
std::vector<rig::MatrixEntry> StandardExperiments(const std::string& labels);

//! A session of the standard matrix's experiments named in `labels`, simulated by the stroke-driven
//! 2dof model at `truth` (sim::SimulatePeriodicSession, no noise), written to `path`.
void WriteTwoDofSession(const std::string& path, const std::string& labels, const ident::ParameterSet& truth);

//! The same at the 2dof model's defaults, which 2dof fits to the noise floor.
void WriteTwoDofSession(const std::string& path, const std::string& labels);

//! The standard matrix simulated by `truth_model` (stroke input) at its defaults with `changes`
//! (--set syntax), its noise from `seed` (sim::SimulatePeriodicSession's default sensors), prepared
//! for a fit of `truth_model` on the n-point grid.
ident::FitData SimulatedFitData(const std::string& truth_model, const std::string& changes, unsigned seed, int n);

//! The default fit of `composition` (every parameter the data determine, stroke input) on the
//! n-point grid.
ident::SessionFitOptions FitOptionsOnGrid(const std::string& composition, int n);

//! A unit drawn (sim::DrawUnit, `seed`) around the shipped truth on an ideal rig: an ideal
//! actuator and calibrated transducers, nothing the damper model leaves out.
sim::Truth DrawnIdealUnit(std::uint64_t seed);

//! DrawnIdealUnit(seed) through the standard matrix on the simulated rig, its noise drawn from `seed`.
daq::Session DrawnUnitSession(std::uint64_t seed);

}  // namespace strut::test
