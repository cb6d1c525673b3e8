// Energy bookkeeping of a transient run of a thermal damper model (heat-exchange term):
//   work in = dissipated + heat to the wall + change of stored energy,
// with work in = integral of F q' dt (the axle force times the stroke rate), the dissipation of the
// orifice, friction, viscous and contact-damping terms (the force terms that are not gravity,
// inertia, gas or constant force), the wall heat theta16 (1 + theta6 q)(T - T_amb), and the stored
// energy theta15 T + theta1 (q'^2 / 2 + g q). The model's heat balance makes this an identity, so
// what does not close is integration and quadrature error. docs/simulated-rig.md.
#pragma once

#include <span>

#include "strut/ident/model.h"
#include "strut/sim/transient.h"

namespace strut::sim {

struct EnergyBudget {
  double work_in = 0.0;        //!< J
  double dissipated = 0.0;     //!< J, into the oil
  double heat_to_wall = 0.0;   //!< J
  double stored_change = 0.0;  //!< J, gas internal energy plus kinetic and potential energy of theta1
  double imbalance() const { return work_in - dissipated - heat_to_wall - stored_change; }
};

//! Budget over the output samples [first, last] (last = -1: the end) of a force-input run (drop
//! tests included), by the trapezoidal rule. Throws std::invalid_argument for a model without
//! heat exchange or a stroke-input result.
EnergyBudget ComputeEnergyBudget(const ident::Model& model, std::span<const double> theta, const TransientResult& result,
                                 long first = 0, long last = -1);
//! The same for a stroke-input run driven by `input` (the measured stroke, q + theta12).
EnergyBudget ComputeEnergyBudget(const ident::Model& model, std::span<const double> theta, const TransientResult& result,
                                 const InputSignal& input, long first = 0, long last = -1);

}  // namespace strut::sim
