// The production-lot study of docs/qc.md (`strut bench qc`): units drawn with the simulated rig's
// manufacturing scatter, a fixed fraction made defective, each run through the QC matrix on the
// simulated rig and decided against the lot's reference: the confusion matrix (true kind against
// PASS / FAIL / UNDECIDED), whether a failed defect names its quantity, the coverage of the
// quantities' 95 % intervals, and the decision time.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "strut/qc/decision.h"
#include "strut/qc/reference.h"
#include "strut/sim/draw.h"
#include "strut/sim/simulated_rig.h"

namespace strut::study {

//! The QC matrix (qc::QcExperiments) as the simulated rig runs it.
rig::MatrixPlan QcMatrix();

//! What can be wrong with a unit of the lot (each a change of the drawn truth, docs/qc.md).
enum class Defect { kNone, kUnderCharge, kExcessFriction, kOilOverfill, kLowOil, kHighOrifice, kLeakingSeal };
const char* ToString(Defect defect);   //!< "good", "under-charge", "excess-friction", "oil-overfill", ...
const std::vector<Defect>& Defects();  //!< every defect kind (not kNone)
//! The QC quantity a defect changes (the one a FAIL must name); "" for kNone.
const char* QuantityOf(Defect defect);

//! The units of the lot: 2 dof with linear seal damping, drawn around the shipped truth on an ideal
//! rig (ideal actuator, calibrated transducers) and feasible for the QC matrix.
sim::UnitDraw LotDraw();
sim::Truth LotUnit(std::uint64_t seed);

//! The lot's reference file (TOML): the design's nominal values with bands around the spread of
//! good drawn units (docs/qc.md).
std::string_view LotReferenceText();
qc::Reference LotReference();

//! `unit` with `defect`: the defect's quantity set to a value drawn from `seed` beyond the
//! reference's limit (docs/qc.md lists the ranges); kNone returns the unit unchanged. Throws
//! std::invalid_argument when the reference has no band for the quantity.
sim::Truth MakeDefective(const sim::Truth& unit, Defect defect, const qc::Reference& reference, std::uint64_t seed);

//! The range of one true quantity over good lot units.
struct QuantityRange {
  std::string name;
  double low = 0.0, high = 0.0;
};
//! The true quantities of `count` good lot units from `first_seed` (the reference's bands come
//! from it), in report order.
std::vector<QuantityRange> TrueQuantityRanges(int count, unsigned long first_seed);

struct LotOptions {
  int units = 200;
  unsigned long first_seed = 5000;
  int defect_tenths = 3;  //!< defective units per ten; the defect kinds take turns
  bool servo = false;     //!< drive through the rig's servo actuator (else an ideal one)
  //! Unit i's kind: defective when i % 10 < defect_tenths.
  Defect KindOf(int i) const;
};

//! One unit's decision.
struct LotUnitResult {
  unsigned long seed = 0;
  Defect kind = Defect::kNone;
  qc::Decision decision;
  std::string rig_error;  //!< why the rig could not run the matrix (the decision is then UNDECIDED)
  double cpu_seconds = 0.0;  //!< of the decision, on this thread
  double sim_seconds = 0.0;  //!< wall time of the rig simulation
  std::vector<std::string> out, guard_band;  //!< quantities out of tolerance (guard band included); in it
  bool named = false;  //!< a quantity out is the one the defect changes
  std::map<std::string, double> z;  //!< (quantity - truth) / sd, fits at the noise floor only
};

struct LotStudy {
  std::string reference;  //!< its source
  std::size_t experiments = 0;  //!< of the QC matrix
  std::vector<std::string> kinds;  //!< "good" and every defect, in table order
  //! kind: verdict: units, for every kind and the three verdicts (PASS, FAIL, UNDECIDED)
  std::map<std::string, std::map<std::string, long>> confusion;
  std::map<std::string, long> named_right;  //!< kind: FAILs naming the defect's quantity
  std::map<std::string, std::pair<long, long>> coverage;  //!< quantity: inside, total
  long guard_band = 0;  //!< guard-band decisions
  long defects_passed = 0, defects = 0, good_failed = 0, good = 0;
  double median_wall = 0.0, median_cpu = 0.0, max_wall = 0.0, median_sim = 0.0;
  std::vector<LotUnitResult> units;
};

//! Unit `i` of the lot (seed first_seed + i): what RunLotStudy decides for it, so that a study split
//! into ranges of units (strut batch) gives the same units.
LotUnitResult DecideLotUnit(const LotOptions& options, int i);
//! The study's figures from its units in unit order (what RunLotStudy gives for them).
LotStudy SummariseLot(std::vector<LotUnitResult> units);

//! A unit as a batch shard keeps it (its decision as report::QcToJson writes it), and back: what
//! SummariseLot and LotUnitLine read.
nlohmann::json LotUnitJson(const LotUnitResult& unit);
LotUnitResult LotUnitFromJson(const nlohmann::json& j);

//! What `strut bench qc` prints: the heading, a line per unit, the summary.
std::string LotHeading(const LotOptions& options);
std::string LotUnitLine(const LotUnitResult& unit);
std::string LotSummary(const LotStudy& study);

//! Runs the study; `on_unit` (may be empty) sees each unit as it ends.
LotStudy RunLotStudy(const LotOptions& options, const std::function<void(const LotUnitResult&)>& on_unit = {});

}  // namespace strut::study
