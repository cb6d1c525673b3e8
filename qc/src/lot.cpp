#include "strut/qc/lot.h"

#include <fmt/format.h>

#include <cmath>
#include <random>
#include <stdexcept>

#include "strut/qc/quantities.h"
#include "strut/sim/draw.h"

namespace strut::qc {
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

const Band& Needs(const Reference& reference, const char* name, Defect defect) {
  const Band* b = reference.find(name);
  if (!b)
    throw std::invalid_argument(fmt::format("the reference {} has no band for {}, which the defect {} changes",
                                            reference.source, name, ToString(defect)));
  return *b;
}

}  // namespace

rig::MatrixPlan QcMatrix() {
  rig::MatrixPlan plan;
  plan.source = "<QC matrix>";
  plan.sample_rate = 200.0;
  plan.periods = 3;
  // label, group, frequency (Hz), static (m), amplitude (m): docs/qc.md says why each is there.
  plan.experiments = {
      {"q1", "middle", 0.1, 0.100, 0.080},  // gas law 20-180 mm, heat exchange, friction at slow reversals
      {"q2", "middle", 0.5, 0.100, 0.030},  // gas stiffness mid-stroke, nearly adiabatic
      {"q3", "middle", 2.0, 0.100, 0.010},  // inertia (moving mass) against the load-cell zero
      {"q4", "low", 1.0, 0.050, 0.040},     // 0.25 m/s: orifice (v^2) apart from seal damping (v)
  };
  return plan;
}

std::string MatrixFileText(const rig::MatrixPlan& plan, const std::string& comment) {
  std::string s;
  std::size_t start = 0;
  while (start <= comment.size() && !comment.empty()) {
    const auto end = comment.find('\n', start);
    s += "# " + comment.substr(start, end == std::string::npos ? std::string::npos : end - start) + "\n";
    if (end == std::string::npos) break;
    start = end + 1;
  }
  if (plan.sample_rate) s += fmt::format("sample_rate = {}\n", *plan.sample_rate);
  if (plan.periods) s += fmt::format("periods = {}\n", *plan.periods);
  for (const auto& e : plan.experiments)
    s += fmt::format("\n[[experiment]]\nlabel = \"{}\"\ngroup = \"{}\"\nfrequency = {}\nstatic_position = {}\n"
                     "amplitude = {}\n",
                     e.label, e.group, e.frequency, e.static_position, e.amplitude);
  return s;
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

sim::UnitDraw LotDraw() {
  sim::UnitDraw draw;
  draw.base = "2dof";
  draw.effects = {{"viscous-damping", std::nullopt}};
  draw.matrix = QcMatrix().experiments;
  return draw;
}

sim::Truth LotUnit(std::uint64_t seed) {
  sim::Truth unit = sim::DrawUnit(sim::WithIdealRig(sim::DefaultTruth()), LotDraw(), seed);
  unit.damper_serial = fmt::format("LOT-{:06d}", seed);
  return unit;
}

std::string_view LotReferenceText() { return kLotReference; }

Reference LotReference() { return ParseNominalFile(kLotReference, "<lot reference>"); }

sim::Truth MakeDefective(const sim::Truth& unit, Defect defect, const Reference& reference, std::uint64_t seed) {
  if (defect == Defect::kNone) return unit;
  const ident::Model model = unit.BuildModel(ident::Causality::kStrokeInput);
  ident::ParameterSet p = unit.Parameters(model);
  std::vector<double>& theta = p.values();
  std::mt19937_64 rng(seed ^ 0x9e3779b97f4a7c15ULL);
  // strut's own uniform from the raw engine output, portable like DrawUnit's.
  const auto uniform = [&](double lo, double hi) {
    return lo + (hi - lo) * sim::UnitUniform(rng());
  };
  const auto charge = [&](double p0) { sim::SetCharge(model, theta, p0); };
  switch (defect) {
    case Defect::kUnderCharge:
      charge(Needs(reference, "charge_pressure", defect).lower * uniform(0.75, 0.92));
      break;
    case Defect::kExcessFriction: {
      double now = NAN;
      for (const Quantity& q : ComputeQuantities(model, theta))
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

}  // namespace strut::qc
