#include "strut/study/lot.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>
#include <stdexcept>

#include "strut/ident/charge.h"
#include "strut/qc/matrix.h"
#include "strut/qc/quantities.h"
#include "strut/sim/transient.h"
#include "strut/study/cpu_time.h"
#include "strut/study/statistics.h"

namespace strut::study {
namespace {

// The lot's reference (docs/qc.md "The lot's reference"): nominal = the shipped design, bands =
// the range of 2000 good drawn units' true values widened by a margin (measured with
// `strut bench qc --truth-ranges`).
constexpr std::string_view kLotReference = R"(# Reference of the simulated production lot (strut bench qc, docs/qc.md).
# Nominal: the shipped design (sim/data/f16-nose-lab.toml, lab charge). Bands: the range of the
# true values of 2000 good units drawn by `strut bench qc --truth-ranges 2000 --first-seed 1`
# (sim::DrawUnit spreads), widened by about 5 % (friction, orifice, heat transfer, seal damping
# more) so a good unit at the edge of the spread is not refused.
model = "2dof+viscous-damping"

[charge_pressure]            # Pa abs at full extension, 20 C; good units 0.494-0.864 MPa
nominal = 7.0e5
lower = 4.7e5
upper = 9.0e5

[gas_column]                 # m, V0 / A; good units 0.2933-0.3106 m
nominal = 0.300
lower = 0.285
upper = 0.320

[friction]                   # N, Coulomb level at the charge; good units 174-519 N
nominal = 351.0
lower = 150.0
upper = 580.0

[orifice_damping]            # N s^2/m^2; good units 4.0e3-1.6e4
nominal = 8.0e3
lower = 3.5e3
upper = 1.8e4

[viscous_damping]            # N s/m, seal drag and leakage; good units 150-599
nominal = 300.0
lower = 0.0
upper = 750.0

[wall_heat_conductance]      # W/K; good units 1.07-2.51
nominal = 1.79
lower = 0.9
upper = 2.9

[load_cell_zero]             # N: the rig's load cell zero; good units -300..300
nominal = 0.0
lower = -400.0
upper = 400.0
)";

double Position(const ident::ParameterSet& p, int index) { return p.position_of_index(index); }

const qc::Band& Needs(const qc::Reference& reference, const char* name, Defect defect) {
  const qc::Band* b = reference.find(name);
  if (!b)
    throw std::invalid_argument(fmt::format("the reference {} has no band for {}, which the defect {} changes",
                                            reference.source, name, ToString(defect)));
  return *b;
}

//! The truth's place in the decision's 95 % intervals.
//! The z of each quantity the truth has (the coverage of its interval).
void MeasureZ(const sim::Truth& truth, const qc::Decision& d, LotUnitResult& unit) {
  const ident::Model model = truth.BuildModel(ident::Causality::kStrokeInput);
  for (const qc::Quantity& t : qc::ComputeQuantities(model, truth.Parameters(model).values()))
    for (const auto& q : d.quantities)
      if (q.quantity.name == t.name && std::isfinite(q.quantity.sd) && q.quantity.sd > 0) {
        unit.z[t.name] = (q.quantity.value - t.value) / q.quantity.sd;
      }
}

LotUnitResult DecideUnit(const LotOptions& options, const qc::Reference& reference, const rig::MatrixPlan& plan,
                         int i) {
  LotUnitResult unit;
  unit.seed = options.first_seed + i;
  unit.kind = options.KindOf(i);
  sim::Truth truth = MakeDefective(LotUnit(unit.seed), unit.kind, reference, unit.seed);
  if (options.servo) truth.actuator.ideal = false;
  const sim::SimulatedRig rig(truth);
  sim::RigRunOptions run;
  run.seed = unit.seed;
  const auto sim_start = std::chrono::steady_clock::now();
  daq::Session session;
  try {
    session = rig.RunMatrix(plan, run);
  } catch (const sim::TransientError& e) {  // a unit the rig cannot run: QC sees an empty session
    unit.rig_error = e.what();
  }
  unit.sim_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - sim_start).count();
  const double before = ThreadSeconds();
  unit.decision = qc::RunQc(session, truth.damper_serial, reference);
  unit.cpu_seconds = ThreadSeconds() - before;
  const qc::Decision& d = unit.decision;
  for (const auto& q : d.quantities) {
    if (q.status != qc::Status::kOut && q.status != qc::Status::kGuardBand) continue;
    unit.out.push_back(q.quantity.name);
    unit.named = unit.named || q.quantity.name == QuantityOf(unit.kind);
    if (q.status == qc::Status::kGuardBand) unit.guard_band.push_back(q.quantity.name);
  }
  if (d.fit_verdict == "at-noise-floor") MeasureZ(truth, d, unit);  // a fit at the noise floor only
  return unit;
}

}  // namespace

rig::MatrixPlan QcMatrix() {
  rig::MatrixPlan plan;
  plan.source = "<QC matrix>";
  plan.sample_rate = qc::kQcSampleRate;
  plan.periods = qc::kQcPeriods;
  plan.experiments = qc::QcExperiments();
  return plan;
}

const char* ToString(Defect defect) {
  switch (defect) {
    case Defect::kNone: return "good";
    case Defect::kUnderCharge: return "under-charge";
    case Defect::kExcessFriction: return "excess-friction";
    case Defect::kOilOverfill: return "oil-overfill";
    case Defect::kLowOil: return "low-oil";
    case Defect::kHighOrifice: return "high-orifice";
    case Defect::kLeakingSeal: return "leaking-seal";
  }
  return "?";
}

const std::vector<Defect>& Defects() {
  static const std::vector<Defect> d = {Defect::kUnderCharge, Defect::kExcessFriction, Defect::kOilOverfill,
                                        Defect::kLowOil,      Defect::kHighOrifice,    Defect::kLeakingSeal};
  return d;
}

const char* QuantityOf(Defect d) {
  switch (d) {
    case Defect::kUnderCharge: return "charge_pressure";
    case Defect::kExcessFriction: return "friction";
    case Defect::kOilOverfill:
    case Defect::kLowOil: return "gas_column";
    case Defect::kHighOrifice: return "orifice_damping";
    case Defect::kLeakingSeal: return "viscous_damping";
    case Defect::kNone: return "";
  }
  return "";
}

sim::UnitDraw LotDraw() {
  sim::UnitDraw draw;
  draw.base = "2dof";
  draw.effects = {{"viscous-damping", std::nullopt}};
  draw.matrix = qc::QcExperiments();
  return draw;
}

sim::Truth LotUnit(std::uint64_t seed) {
  sim::Truth unit = sim::DrawUnit(sim::WithIdealRig(sim::DefaultTruth()), LotDraw(), seed);
  unit.damper_serial = fmt::format("LOT-{:06d}", seed);
  return unit;
}

std::string_view LotReferenceText() { return kLotReference; }

qc::Reference LotReference() { return qc::ParseNominalFile(kLotReference, "<lot reference>"); }

sim::Truth MakeDefective(const sim::Truth& unit, Defect defect, const qc::Reference& reference, std::uint64_t seed) {
  if (defect == Defect::kNone) return unit;
  const ident::Model model = unit.BuildModel(ident::Causality::kStrokeInput);
  ident::ParameterSet p = unit.Parameters(model);
  std::vector<double>& theta = p.values();
  std::mt19937_64 rng(seed ^ 0x9e3779b97f4a7c15ULL);
  // strut's own uniform from the raw engine output, portable like DrawUnit's.
  const auto uniform = [&](double lo, double hi) {
    return lo + (hi - lo) * sim::UnitUniform(rng());
  };
  const auto charge = [&](double p0) { ident::SetCharge(model, theta, p0); };
  switch (defect) {
    case Defect::kUnderCharge:
      charge(Needs(reference, "charge_pressure", defect).lower * uniform(0.75, 0.92));
      break;
    case Defect::kExcessFriction: {
      double now = NAN;
      for (const qc::Quantity& q : qc::ComputeQuantities(model, theta))
        if (q.name == "friction") now = q.value;
      const double target = Needs(reference, "friction", defect).upper * uniform(1.15, 1.8);
      theta[Position(p, 8)] *= target / now;
      theta[Position(p, 9)] *= target / now;
      break;
    }
    case Defect::kOilOverfill:  // the same charge pressure in less gas volume: the gas column shortens
      theta[Position(p, 6)] = -1.0 / (Needs(reference, "gas_column", defect).lower * uniform(0.85, 0.95));
      break;
    case Defect::kLowOil:
      theta[Position(p, 6)] = -1.0 / (Needs(reference, "gas_column", defect).upper * uniform(1.08, 1.3));
      break;
    case Defect::kHighOrifice:
      theta[Position(p, 3)] = Needs(reference, "orifice_damping", defect).upper * uniform(1.15, 1.8);
      break;
    case Defect::kLeakingSeal:
      // Gas lost past the worn seal, whose torn lip also drags and lets oil by: a charge just
      // under its limit and a linear damping far above the seal's range.
      charge(Needs(reference, "charge_pressure", defect).lower * uniform(0.85, 0.97));
      theta[Position(p, 18)] = Needs(reference, "viscous_damping", defect).upper * uniform(1.5, 3.0);
      break;
    case Defect::kNone:
      break;
  }
  sim::Truth out = unit;
  for (int i = 0; i < p.size(); ++i) out.parameters.emplace_back(p.spec(i).name, theta[i]);
  out.damper_serial = unit.damper_serial + "-" + ToString(defect);
  return out;
}

std::vector<QuantityRange> TrueQuantityRanges(int count, unsigned long first_seed) {
  std::vector<QuantityRange> ranges;
  for (int i = 0; i < count; ++i) {
    const sim::Truth unit = LotUnit(first_seed + i);
    const ident::Model model = unit.BuildModel(ident::Causality::kStrokeInput);
    for (const qc::Quantity& q : qc::ComputeQuantities(model, unit.Parameters(model).values())) {
      auto r = std::find_if(ranges.begin(), ranges.end(), [&](const QuantityRange& x) { return x.name == q.name; });
      if (r == ranges.end()) {
        ranges.push_back({q.name, q.value, q.value});
        continue;
      }
      r->low = std::min(r->low, q.value);
      r->high = std::max(r->high, q.value);
    }
  }
  return ranges;
}

Defect LotOptions::KindOf(int i) const {
  if (i % 10 >= defect_tenths) return Defect::kNone;
  const int k = (i / 10) * defect_tenths + i % 10;
  return Defects()[k % Defects().size()];
}

LotUnitResult DecideLotUnit(const LotOptions& options, int i) {
  return DecideUnit(options, LotReference(), QcMatrix(), i);
}

LotStudy SummariseLot(std::vector<LotUnitResult> units) {
  LotStudy study;
  study.reference = LotReference().source;
  study.experiments = QcMatrix().experiments.size();
  study.kinds = {"good"};
  for (Defect d : Defects()) study.kinds.push_back(ToString(d));
  std::vector<double> wall, cpu, sim_seconds;
  for (const LotUnitResult& unit : units) {
    const qc::Decision& d = unit.decision;
    ++study.confusion[ToString(unit.kind)][qc::ToString(d.verdict)];
    study.guard_band += static_cast<long>(unit.guard_band.size());
    if (unit.kind != Defect::kNone && d.verdict == qc::Verdict::kFail && unit.named) ++study.named_right[ToString(unit.kind)];
    for (const auto& [name, z] : unit.z) {
      study.coverage[name].first += std::abs(z) < qc::kGuardBandSigmas;
      study.coverage[name].second += 1;
    }
    wall.push_back(d.seconds);
    cpu.push_back(unit.cpu_seconds);
    sim_seconds.push_back(unit.sim_seconds);
  }
  study.units = std::move(units);
  for (const auto& k : study.kinds) {
    auto& row = study.confusion[k];  // every kind and verdict gets its entry, 0 when none was decided so
    const long total = row["PASS"] + row["FAIL"] + row["UNDECIDED"];
    if (k == "good") {
      study.good += total;
      study.good_failed += row["FAIL"];
    } else {
      study.defects += total;
      study.defects_passed += row["PASS"];
    }
  }
  study.median_wall = Median(wall);
  study.median_cpu = Median(cpu);
  study.median_sim = Median(sim_seconds);
  study.max_wall = wall.empty() ? NAN : *std::max_element(wall.begin(), wall.end());
  return study;
}

LotStudy RunLotStudy(const LotOptions& options, const std::function<void(const LotUnitResult&)>& on_unit) {
  const qc::Reference reference = LotReference();
  const rig::MatrixPlan plan = QcMatrix();
  std::vector<LotUnitResult> units;
  for (int i = 0; i < options.units; ++i) {
    units.push_back(DecideUnit(options, reference, plan, i));
    if (on_unit) on_unit(units.back());
  }
  return SummariseLot(std::move(units));
}

}  // namespace strut::study
