// The QC test and the production-lot study (docs/qc.md): the QC matrix the rig runs, the
// reference of the simulated lot, and defective units made from drawn ones.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "strut/qc/reference.h"
#include "strut/sim/draw.h"
#include "strut/sim/simulated_rig.h"

namespace strut::qc {

//! The QC matrix: four experiments, 2.5 minutes on the rig (docs/qc.md gives the reasoning).
rig::MatrixPlan QcMatrix();

//! A matrix plan as a matrix file (TOML, docs/simulated-rig.md "Matrix files"), each line of
//! `comment` as a leading comment.
std::string MatrixFileText(const rig::MatrixPlan& plan, const std::string& comment);

//! What can be wrong with a unit of the lot (each a change of the drawn truth, docs/qc.md).
enum class Defect { kNone, kUnderCharge, kExcessFriction, kOilOverfill, kLowOil, kHighOrifice, kLeakingSeal };
const char* ToString(Defect defect);  //!< "good", "under-charge", "excess-friction", "oil-overfill", ...
const std::vector<Defect>& Defects();  //!< every defect kind (not kNone)

//! The units of the lot: 2 dof with linear seal damping, drawn around the shipped truth on an ideal
//! rig (ideal actuator, calibrated transducers) and feasible for the QC matrix.
sim::UnitDraw LotDraw();
sim::Truth LotUnit(std::uint64_t seed);

//! The lot's reference file (TOML): the design's nominal values with bands around the spread of
//! good drawn units (docs/qc.md).
std::string_view LotReferenceText();
Reference LotReference();

//! `unit` with `defect`: the defect's quantity set to a value drawn from `seed` beyond the
//! reference's limit (docs/qc.md lists the ranges); kNone returns the unit unchanged. Throws
//! std::invalid_argument when the reference has no band for the quantity.
sim::Truth MakeDefective(const sim::Truth& unit, Defect defect, const Reference& reference, std::uint64_t seed);

}  // namespace strut::qc
