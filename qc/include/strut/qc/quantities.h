// The physical quantities production QC judges a damper by (docs/qc.md), computed from a fitted
// parameter set: gas charge, gas volume (oil level), seal friction, orifice damping, viscous (seal
// leak) damping, wall heat transfer, and the two sensor offsets. Their sd comes from the fit's
// posterior covariance by linearisation (central differences of each quantity in the estimated
// parameters).
#pragma once

#include <string>
#include <vector>

#include "strut/ident/estimator.h"
#include "strut/ident/model.h"

namespace strut::qc {

//! Names of the QC quantities, in report order.
//! charge_pressure (Pa abs at full extension and ambient temperature), gas_column (m: the gas volume
//! at full extension over the piston area, V0/A = -1/theta6; the oil level), friction (N, Coulomb level at the charge (theta8 + theta9 p0) pi/2),
//! orifice_damping (theta3), viscous_damping (theta18, when the model has the term),
//! wall_heat_conductance (theta16, with heat exchange), stroke_offset (theta12), load_cell_zero
//! (N, theta11 + theta39 + p_atm theta4: the force reading of a damper at atmospheric pressure).
const std::vector<std::string>& QuantityNames();

struct Quantity {
  std::string name;
  std::string unit;
  std::string description;  //!< one line: what it is physically
  double value = 0.0;
  double sd = 0.0;          //!< NaN: the fit did not estimate what it depends on
};

//! The quantities of `model` (stroke input) at `theta`; sd NaN. Quantities the model has no
//! parameters for are left out. Throws ident::ModelError when the charge cannot be solved.
std::vector<Quantity> ComputeQuantities(const ident::Model& model, const std::vector<double>& theta);

//! The quantities at a fit's estimate, each with its sd from the fit's covariance (the estimated
//! parameters' sd and correlation). A quantity none of whose parameters was estimated has sd NaN.
std::vector<Quantity> ComputeQuantities(const ident::Model& model, const ident::FitSummary& fit);

}  // namespace strut::qc
