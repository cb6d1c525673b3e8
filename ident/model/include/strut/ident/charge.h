// The gas charge of a damper model: what a technician sets at full extension, read from the model's
// static equilibrium (QC judges it; the simulated rig draws and defects set it).
#pragma once

#include <vector>

#include "strut/ident/model.h"

namespace strut::ident {

//! The gas pressure (Pa abs) at full extension and ambient temperature: the static state of a
//! stroke-input `model` at true stroke 0 (the charge a technician sets). Throws ModelError when
//! the model has no gas pressure or Newton fails.
double ChargePressure(const Model& model, const std::vector<double>& theta);

//! Sets theta5 (extended pressure or pressure per temperature) so that ChargePressure is `p0`, and
//! the oil compliance's reference pressure (theta27, when present) to `p0`: a few fixed-point steps
//! (p is nearly proportional to theta5; solubility and real gas bend it).
void SetCharge(const Model& model, std::vector<double>& theta, double p0);

}  // namespace strut::ident
