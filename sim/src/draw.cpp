#include "strut/sim/draw.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <numbers>
#include <random>

#include "strut/daq/session.h"
#include "strut/ident/charge.h"
#include "strut/ident/estimator.h"
#include "strut/ident/model.h"
#include "strut/ident/periodic.h"

namespace strut::sim {
namespace {

constexpr double kPatm = daq::kGaugeReferencePa;
constexpr double kHalfPi = std::numbers::pi / 2.0;
// Periodic grid of the feasibility check, and how far (m) above the matrix's deepest set-point
// stroke an experiment must reach to be checked (the peak force follows the deepest stroke).
constexpr int kCheckGrid = 200;
constexpr double kDeepWindow = 0.02;
// The matrix stays at least this far inside full extension (true stroke), m.
constexpr double kTopOutMargin = 1e-3;
constexpr double kMinCompressionRatio = 5.0, kMaxCompressionRatio = 12.0;
// Periodic grid of an effect's signal: the fits' default, so the signal is what a fit resolves.
constexpr int kSignalGrid = 800;

const std::vector<std::string> kBases = {"1dof", "1dof+heat-exchange", "2dof"};
const std::vector<std::string> kExtraEffectNames = {"viscous-damping", "stribeck-friction", "end-stop",
                                                "oil-compressibility", "real-gas", "dead-volume",
                                                "recoil-damping", "metering-pin", "friction-asymmetry",
                                                "pressure-heat-transfer", "charge-loss"};
// Spreads drawn only for units that have their effect (they came after the others, so every other
// unit of a seed is the one it was before they were added).
const std::vector<std::string> kDrawnOnlyWithTheEffect = {"end_stop_position", "dead_volume_ratio",
                                                          "recoil_damping_excess", "metering_pin_gradient",
                                                          "friction_asymmetry", "heat_transfer_pressure_gain",
                                                          "charge_lost"};

//! Random numbers whose values the C++ standard fixes (mt19937_64 is fully specified; the
//! library's distributions are not), so a seed gives the same unit with every compiler.
class Draws {
 public:
  explicit Draws(std::uint64_t seed) : engine_(seed) {}
  double Uniform() { return UnitUniform(engine_()); }  // [0, 1)
  double Normal() {  // Box-Muller, two uniforms per value
    const double u1 = 1.0 - Uniform(), u2 = Uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
  }
  //! One value of a spread around x0 (always takes the same count of numbers for a kind).
  double Draw(const DrawSpread& s, double x0) {
    switch (s.kind) {
      case SpreadKind::kUniformFactor: return x0 * (s.low + (s.high - s.low) * Uniform());
      case SpreadKind::kLogUniformFactor:
        return x0 * std::exp(std::log(s.low) + (std::log(s.high) - std::log(s.low)) * Uniform());
      case SpreadKind::kUniformOffset: return x0 + s.low + (s.high - s.low) * Uniform();
      case SpreadKind::kNormalOffset: return x0 + std::clamp(s.low * Normal(), -s.high, s.high);
    }
    return x0;
  }

 private:
  std::mt19937_64 engine_;
};

bool Contains(const std::vector<std::string>& list, std::string_view name) {
  return std::find(list.begin(), list.end(), name) != list.end();
}

double Value(const ident::ParameterSet& p, int index) { return p.value(p.position_of_index(index)); }

}  // namespace

const std::vector<std::string>& ExtraEffects() { return kExtraEffectNames; }

const std::vector<DrawSpread>& DrawSpreads() {
  using K = SpreadKind;
  static const std::vector<DrawSpread> spreads = {
      {"moving_mass", "theta1", K::kUniformFactor, 0.5, 1.5, "all", "§1.3: shaker moving mass 20-60 kg"},
      {"orifice_damping", "theta3", K::kLogUniformFactor, 0.5, 2.0, "all",
       "§1.3: 4e3-2e4 N s^2/m^2; §1.2: Cd 0.6-0.9 alone moves it by 2.25x"},
      {"gas_area", "theta4", K::kUniformFactor, 0.8, 1.2, "all", "§1.2, §1.3: 4.0-6.5e-3 m^2"},
      {"compression_ratio", "theta6", K::kUniformFactor, 0.8, 1.2, "all",
       "§1.2: 5-12 at 0.264 m (8.3 nominal); V0 = A s CR / (CR - 1) = 1.2-2.0 L"},
      {"preload_fraction", "theta5", K::kUniformFactor, 0.8, 1.0, "all",
       "§1.1: the lab charge keeps (p0 - p_atm) A + friction below the drop mass's weight"},
      {"polytropic_exponent", "theta7", K::kUniformOffset, -0.15, 0.15, "1dof", "§1.3, §1.4: 1.0-1.4 (1.05-1.35)"},
      {"gas_solubility", "theta7", K::kUniformFactor, 0.0, 2.0, "gas-solubility", "§2.2: 0-5e-5 1/K"},
      {"friction_base", "theta8", K::kUniformFactor, 0.5, 1.5, "all", "§1.3: 100-320 N"},
      {"friction_pressure", "theta9", K::kUniformFactor, 0.5, 1.5, "all", "§1.3: 2e-5-1e-4 m^2"},
      {"friction_sharpness", "theta10", K::kUniformFactor, 0.5, 1.5, "all", "§1.3: 500-2e4 s/m"},
      {"load_cell_zero", "theta11", K::kNormalOffset, 100.0, 300.0, "all",
       "§1.3, §1.7: theta11 = -p_atm A + a load-cell zero of about 100 N"},
      {"stroke_offset", "theta12", K::kNormalOffset, 2e-3, 5e-3, "all", "§1.3: LVDT zero within 5 mm of nominal (sd 2 mm, the prior identify puts on it)"},
      {"gas_heat_capacity", "theta15", K::kUniformFactor, 0.6, 1.4, "heat-exchange",
       "§1.3, §1.4: kappa m c_v with kappa 1-3 (nominal 2)"},
      {"wall_heat_conductance", "theta16", K::kUniformFactor, 0.6, 1.4, "heat-exchange",
       "§1.3: tau0 = theta15 / theta16 about 8 s"},
      {"viscous_damping", "theta18", K::kLogUniformFactor, 0.5, 2.0, "viscous-damping",
       "§2.6, §2.8: 100-1500 N s/m"},
      {"stribeck_excess", "theta19", K::kUniformFactor, 0.5, 1.5, "stribeck-friction", "§2.8: F_S / F_C 1.2-1.5"},
      {"end_stop_stiffness", "theta21", K::kLogUniformFactor, 0.5, 2.0, "end-stop", "§2.9: 2e6-1e7 N/m"},
      {"oil_compliance", "theta26", K::kUniformFactor, 0.75, 1.25, "oil-compressibility",
       "§1.2, §2.3: 0.8-1.5 GPa"},
      {"virial_gain", "theta31", K::kUniformFactor, 1.0, 1.0, "real-gas",
       "§2.10: nitrogen's virial coefficients are not the unit's: not drawn (gain 1 = N2 as it is)"},
      // Last, so the quantities above take the same random numbers as before it was added.
      {"end_stop_position", "theta23", K::kUniformOffset, 0.0, 8e-3, "end-stop",
       "§2.9: a top-out snubber of a few mm engages 0-8 mm inside full extension (the matrix's "
       "shallowest experiments come within about 4 mm of it)"},
      {"dead_volume_ratio", "theta36", K::kUniformFactor, 0.6, 2.0, "dead-volume",
       "§2.4: V_d 3-10 cm^3 of line, fittings and transducer cavity over V0 1.6 L (nominal 5 cm^3)"},
      {"recoil_damping_excess", "theta32", K::kUniformFactor, 0.67, 2.67, "recoil-damping",
       "§2.6: c_ext = (2-5) c_comp from snubber or flapper valves (nominal x2.5)"},
      {"metering_pin_gradient", "theta33", K::kUniformFactor, 0.5, 2.0, "metering-pin",
       "§2.7: a pin closing 15-50 % of the orifice area over the stroke (nominal 30 %)"},
      {"friction_asymmetry", "theta34", K::kUniformFactor, -1.5, 1.5, "friction-asymmetry",
       "§2.8: compression and extension friction differ by up to +-30 %"},
      {"heat_transfer_pressure_gain", "theta35", K::kUniformFactor, 0.5, 1.0, "pressure-heat-transfer",
       "§2.1: natural convection, h growing as (p / p0)^(2/3) (weight 0.5-1 of the full law)"},
      {"charge_lost", "theta37", K::kUniformFactor, 0.5, 2.0, "charge-loss",
       "§2.11: gas leaking through the seals, 0.5-2 % of the charge over a session (nominal 1 %)"},
  };
  return spreads;
}

void UnitDraw::Validate() const {
  if (!Contains(kBases, base))
    throw TruthError(fmt::format("draw: unknown base '{}' (known: 1dof, 1dof+heat-exchange, 2dof)", base));
  std::vector<std::string> seen;
  for (const EffectRequest& e : effects) {
    if (!Contains(ExtraEffects(), e.name))
      throw TruthError(fmt::format("draw: unknown effect '{}' (known: {})", e.name, fmt::join(ExtraEffects(), ", ")));
    if (Contains(seen, e.name)) throw TruthError(fmt::format("draw: effect '{}' given twice", e.name));
    seen.push_back(e.name);
    if (e.size && !(std::isfinite(*e.size) && *e.size > 0))
      throw TruthError(fmt::format("draw: effect '{}': the size must be a positive number, got {}", e.name, *e.size));
  }
  std::string composition = base;
  for (const EffectRequest& e : effects) composition += "+" + e.name;
  try {
    ident::Model::Build(composition, ident::Causality::kStrokeInput);
  } catch (const ident::ModelError& e) {
    throw TruthError(fmt::format("draw: the base {} cannot have these effects: {}", base, e.what()));
  }
  if (matrix.empty()) throw TruthError("draw: the feasibility matrix has no experiments");
  if (max_attempts < 1) throw TruthError(fmt::format("draw: max_attempts must be at least 1, got {}", max_attempts));
  if (!(drop_mass >= 0) || !std::isfinite(drop_mass))
    throw TruthError(fmt::format("draw: drop_mass must be zero (no drop rule) or positive, got {}", drop_mass));
}

Feasibility CheckFeasibility(const Truth& unit, const std::vector<rig::MatrixEntry>& matrix, double drop_mass) {
  Feasibility f;
  const auto fail = [&](std::string reason) {
    f.feasible = false;
    f.reason = std::move(reason);
    return f;
  };
  const ident::Model model = unit.BuildModel(ident::Causality::kStrokeInput);
  const ident::ParameterSet p = unit.Parameters(model);
  const std::vector<double>& theta = p.values();
  const double per_stroke = Value(p, 6), offset = Value(p, 12), area = Value(p, 4);
  const double end_volume = 1.0 + per_stroke * kFullStroke;
  f.compression_ratio = end_volume > 0 ? 1.0 / end_volume : INFINITY;
  double deepest = 0.0, shallowest = INFINITY;
  for (const auto& e : matrix) {
    deepest = std::max(deepest, e.static_position + e.amplitude);
    shallowest = std::min(shallowest, e.static_position - e.amplitude);
  }
  f.min_stroke = shallowest - offset;
  try {
    f.charge_pressure = ident::ChargePressure(model, theta);
  } catch (const ident::ModelError& e) {
    return fail(fmt::format("no static state at full extension: {}", e.what()));
  }
  const double gravity = Value(p, 2);
  const double coulomb = (Value(p, 8) + Value(p, 9) * f.charge_pressure) * kHalfPi;
  f.drop_margin = drop_mass * gravity - (f.charge_pressure - kPatm) * area - coulomb;
  if (!(f.compression_ratio >= kMinCompressionRatio && f.compression_ratio <= kMaxCompressionRatio))
    return fail(fmt::format("compression ratio {:.2f} at {} m is outside {}..{}", f.compression_ratio, kFullStroke,
                            kMinCompressionRatio, kMaxCompressionRatio));
  if (1.0 + per_stroke * (deepest - offset) <= 0)
    return fail(fmt::format("the gas volume reaches zero at the deepest stroke {:.4f} m", deepest - offset));
  if (f.min_stroke < kTopOutMargin)
    return fail(fmt::format("the matrix reaches a true stroke of {:.1f} mm (stroke offset {:.1f} mm): within {} mm "
                            "of full extension",
                            f.min_stroke * 1e3, offset * 1e3, kTopOutMargin * 1e3));
  if (drop_mass > 0 && f.drop_margin < 0)
    return fail(fmt::format("a {} kg drop would not stay compressed: preload plus friction exceed its weight by {:.0f} N",
                            drop_mass, -f.drop_margin));
  const double limit = unit.actuator.ideal ? 0.0 : unit.actuator.force_limit;
  ident::PeriodicSolver solver(model);
  for (const auto& e : matrix) {
    if (e.static_position + e.amplitude < deepest - kDeepWindow) continue;
    try {
      const ident::PeriodicSolution s =
          solver.Solve(ident::PeriodicInput::Sine(e.frequency, e.static_position, e.amplitude, kCheckGrid), theta);
      f.peak_force = std::max(f.peak_force, s.channel("force").cwiseAbs().maxCoeff());
    } catch (const ident::PeriodicSolverError& error) {
      return fail(fmt::format("experiment '{}': no periodic steady state: {}", e.label, error.what()));
    }
  }
  if (limit > 0 && f.peak_force > kForceLimitMargin * limit)
    return fail(fmt::format("peak force {:.1f} kN exceeds {:.0f} % of the actuator's force limit {:.1f} kN",
                            f.peak_force * 1e-3, 100 * kForceLimitMargin, limit * 1e-3));
  return f;
}

namespace {

//! What one attempt of DrawUnit draws beside the parameters it sets in place: the gas area, the
//! compression ratio, the preload fraction, the load cell's zero, and the sizes of the extra effects.
struct DrawnQuantities {
  double area = 0.0, ratio = 0.0, fraction = 0.0, zero = 0.0;
  std::vector<EffectSize> sizes;
};

bool Has(const ident::ParameterSet& p, int index) { return p.position_of_index(index) >= 0; }
void Set(ident::ParameterSet& p, int index, double v) { p.values()[p.position_of_index(index)] = v; }

//! One attempt's draws: every spread of DrawSpreads in turn, the parameters among them set in `p`
//! (the base's values around which they are drawn), the others returned, each around `start`'s.
DrawnQuantities DrawAttempt(Draws& draws, const UnitDraw& spec, const ident::ParameterSet& base,
                            const DrawnQuantities& start, ident::ParameterSet& p) {
  DrawnQuantities d = start;
  // Every spread takes its random numbers on every attempt, whether it applies or not: the
  // quantities a base shares with another are then the same for the same seed.
  for (const DrawSpread& s : DrawSpreads()) {
    if (Contains(kDrawnOnlyWithTheEffect, s.quantity) &&
        std::none_of(spec.effects.begin(), spec.effects.end(), [&](const EffectRequest& r) { return r.name == s.applies; }))
      continue;
    const int index = std::stoi(s.sets.substr(5));
    const double x0 = s.quantity == "compression_ratio" ? start.ratio
                      : s.quantity == "preload_fraction" ? start.fraction
                      : s.quantity == "load_cell_zero"   ? start.zero
                      : s.quantity == "stroke_offset"    ? 0.0  // around the lab's nominal zero
                      : Has(p, index) ? Value(base, index) : 0.0;
    const double x = draws.Draw(s, x0);
    if (s.quantity == "gas_area") {
      d.area = x;
    } else if (s.quantity == "compression_ratio") {
      d.ratio = x;
    } else if (s.quantity == "preload_fraction") {
      d.fraction = x;
    } else if (s.quantity == "load_cell_zero") {
      d.zero = x;
    } else if (s.quantity == "polytropic_exponent" || s.quantity == "gas_solubility") {
      if (Has(p, index) && p.spec(p.position_of_index(index)).name == s.quantity) Set(p, index, x);
    } else if (s.applies != "all" && s.applies != "heat-exchange" && Contains(ExtraEffects(), s.applies)) {
      const auto request = std::find_if(spec.effects.begin(), spec.effects.end(),
                                        [&](const EffectRequest& r) { return r.name == s.applies; });
      if (request == spec.effects.end()) continue;
      // The first spread of an effect is its size (EffectRequest::size); later ones its shape.
      const bool sizing = std::none_of(d.sizes.begin(), d.sizes.end(), [&](const EffectSize& e) { return e.effect == s.applies; });
      const double size = sizing ? request->size.value_or(x) : x;
      Set(p, index, size);
      if (sizing) d.sizes.push_back({s.applies, s.sets, size, request->size.has_value()});
    } else if (Has(p, index)) {
      Set(p, index, x);
    }
  }
  return d;
}

}  // namespace

Truth DrawUnit(const UnitDraw& spec, std::uint64_t seed) { return DrawUnit(DefaultTruth(), spec, seed); }

Truth DrawUnit(const Truth& around, const UnitDraw& spec, std::uint64_t seed) {
  spec.Validate();
  around.Validate();
  // The base: the around-truth's values, by parameter name, in its own model.
  const ident::Model around_model = around.BuildModel(ident::Causality::kStrokeInput);
  const ident::ParameterSet around_values = around.Parameters(around_model);
  double base_charge = 0.0;
  try {
    base_charge = ident::ChargePressure(around_model, around_values.values());
  } catch (const ident::ModelError& e) {
    throw TruthError(fmt::format("{}: no static state at full extension to draw around: {}", around.source, e.what()));
  }

  Truth unit = around;
  unit.effects.clear();
  for (const std::string& e : Truth::EffectNames()) {
    const bool in_base = (e == "heat-exchange" && spec.base != "1dof") || (e == "gas-solubility" && spec.base == "2dof");
    const bool extra = std::any_of(spec.effects.begin(), spec.effects.end(),
                                   [&](const EffectRequest& r) { return r.name == e; });
    if (in_base || extra) unit.effects.push_back(e);
  }
  const ident::Model model = unit.BuildModel(ident::Causality::kStrokeInput);
  ident::ParameterSet base = model.defaults();
  for (int i = 0; i < base.size(); ++i)
    if (const auto j = around_values.find(base.spec(i).name)) base.values()[i] = around_values.value(*j);

  const double gravity = Value(base, 2);
  const double a0 = Value(around_values, 4);
  // The base's charge as a fraction of the drop budget m g - Coulomb friction (0.97 shipped).
  const double budget0 = spec.drop_mass * gravity - (Value(around_values, 8) + Value(around_values, 9) * base_charge) * kHalfPi;
  const bool drop_rule = spec.drop_mass > 0 && budget0 > 0 && (base_charge - kPatm) * a0 <= budget0;
  const double k0 = drop_rule ? (base_charge - kPatm) * a0 / budget0 : 1.0;
  if (!drop_rule)
    spdlog::info("draw: {} is not drop-consistent (a {} kg drop would top out); the charge is drawn without the drop rule",
                 around.source, spec.drop_mass);
  const double ratio0 = 1.0 / (1.0 + Value(around_values, 6) * kFullStroke);
  const double zero0 = Value(around_values, 11) + kPatm * a0;

  const DrawnQuantities start{a0, ratio0, k0, zero0, {}};
  Draws draws(seed);
  DrawRecord record;
  record.seed = seed;
  record.base = spec.base;
  record.around = around.source;
  std::string last_reason;
  for (int attempt = 1; attempt <= spec.max_attempts; ++attempt) {
    ident::ParameterSet p = base;
    DrawnQuantities drawn = DrawAttempt(draws, spec, base, start, p);
    const double area = drawn.area, fraction = drawn.fraction;
    Set(p, 4, area);
    Set(p, 6, -(1.0 - 1.0 / drawn.ratio) / kFullStroke);
    Set(p, 11, -kPatm * area + drawn.zero);
    // The charge: (p0 - p_atm) A = k (m g - (theta8 + theta9 p0) pi / 2), solved for p0.
    double p0 = 0.0;
    if (drop_rule) {
      p0 = (kPatm * area + fraction * (spec.drop_mass * gravity - Value(p, 8) * kHalfPi)) /
           (area + fraction * Value(p, 9) * kHalfPi);
    } else {
      p0 = kPatm + (base_charge - kPatm) * (a0 / area) * fraction;
    }
    try {
      ident::SetCharge(model, p.values(), p0);
    } catch (const ident::ModelError& e) {
      last_reason = fmt::format("no static state at full extension: {}", e.what());
      continue;
    }
    std::sort(drawn.sizes.begin(), drawn.sizes.end(), [](const EffectSize& a, const EffectSize& b) {
      const auto& n = Truth::EffectNames();
      return std::find(n.begin(), n.end(), a.effect) < std::find(n.begin(), n.end(), b.effect);
    });
    unit.parameters.clear();
    for (int i = 0; i < p.size(); ++i) unit.parameters.emplace_back(p.spec(i).name, p.value(i));
    record.effects = drawn.sizes;
    record.attempts = attempt;
    unit.drawn = record;
    unit.source = fmt::format("drawn unit (seed {}, {}, around {})", seed, model.composition(), around.source);
    unit.damper_serial = fmt::format("{}-D{}", around.damper_serial, seed);
    if (!spec.feasible_only) return unit;
    const Feasibility f = CheckFeasibility(unit, spec.matrix, drop_rule ? spec.drop_mass : 0.0);
    if (f.feasible) return unit;
    last_reason = f.reason;
    spdlog::debug("draw seed {} attempt {}: infeasible: {}", seed, attempt, f.reason);
  }
  throw TruthError(fmt::format("draw: no feasible {} unit in {} attempts from seed {} (last: {})", model.composition(),
                               spec.max_attempts, seed, last_reason));
}

Truth WithIdealRig(Truth truth) {
  truth.actuator.ideal = true;
  for (SensorOptions* s : {&truth.sensors.stroke, &truth.sensors.force, &truth.sensors.pressure})
    s->offset = s->gain_error = 0.0;
  return truth;
}

EffectSignal MeasureEffectSignal(const Truth& unit, std::string_view effect, const std::vector<rig::MatrixEntry>& matrix) {
  if (!unit.has_effect(effect)) throw TruthError(fmt::format("{}: the unit has no effect '{}'", unit.source, effect));
  const ident::Model model = unit.BuildModel(ident::Causality::kStrokeInput);
  const std::vector<double> with = unit.Parameters(model).values();
  // The effect's sizing parameters are those the unit's model has and the model without the
  // effect has not; every catalogue effect is absent at a size of 0.
  Truth without = unit;
  std::erase(without.effects, std::string(effect));
  const ident::ParameterSet reduced = without.BuildModel(ident::Causality::kStrokeInput).defaults();
  std::vector<double> neutral = with;
  bool sized = false;
  for (int i = 0; i < model.parameter_count(); ++i) {
    const ident::ParameterSpec& spec = model.defaults().spec(i);
    if (spec.sizes_term && !reduced.find(spec.name)) {
      neutral[i] = 0.0;
      sized = true;
    }
  }
  if (!sized) throw TruthError(fmt::format("{}: effect '{}' has no sizing parameter", unit.source, effect));
  const std::pair<const char*, double> channels[] = {{"force", unit.sensors.force.noise},
                                                     {"pressure", unit.sensors.pressure.noise}};
  for (const auto& [name, sd] : channels)
    if (!(sd > 0)) throw TruthError(fmt::format("{}: the {} channel has no noise to measure a signal in", unit.source, name));

  // What the baseline estimates (by name in the unit's model), scaled as the estimator scales.
  const std::vector<ident::ParameterChoice> choices = ident::DefaultChoices(reduced);
  std::vector<int> estimated;
  std::vector<double> scale, prior_weight;
  for (int i = 0; i < reduced.size(); ++i) {
    if (!choices[i].estimate) continue;
    const int position = *model.defaults().find(reduced.spec(i).name);
    estimated.push_back(position);
    scale.push_back(std::max(std::abs(neutral[position]), reduced.spec(i).typical_size()));
    prior_weight.push_back(choices[i].prior_sd ? scale.back() / *choices[i].prior_sd : 0.0);
  }
  const int k = static_cast<int>(estimated.size()), blocks = static_cast<int>(matrix.size()) * 2;
  // Rows in the fit's weights: each grid point over the averaged data's noise sd (sd / sqrt(periods)).
  const double per_average = std::sqrt(static_cast<double>(unit.acquisition.periods));
  Eigen::MatrixXd sensitivity = Eigen::MatrixXd::Zero(blocks * kSignalGrid + k, k);
  Eigen::VectorXd difference = Eigen::VectorXd::Zero(blocks * kSignalGrid + k);

  EffectSignal signal;
  ident::PeriodicSolver solver(model);
  for (std::size_t a = 0; a < matrix.size(); ++a) {
    const rig::MatrixEntry& e = matrix[a];
    const ident::PeriodicInput input = ident::PeriodicInput::Sine(e.frequency, e.static_position, e.amplitude, kSignalGrid);
    ident::PeriodicSolution on, off;
    std::vector<Eigen::MatrixXd> d_outputs;
    try {
      const double session_time = daq::OrderSessionTime(a, matrix.size());
      const std::vector<double> with_at = model.AtExperiment(with, {session_time, e.static_position});
      const std::vector<double> neutral_at = model.AtExperiment(neutral, {session_time, e.static_position});
      on = solver.Solve(input, with_at);
      off = solver.Solve(input, neutral_at, &on);
      d_outputs = solver.OutputSensitivities(off, neutral_at, estimated);
    } catch (const ident::PeriodicSolverError& error) {
      throw TruthError(fmt::format("{}: experiment '{}': no periodic steady state: {}", unit.source, e.label, error.what()));
    }
    const double samples = static_cast<double>(unit.acquisition.periods) * unit.acquisition.sample_rate / e.frequency;
    for (int c = 0; c < 2; ++c) {
      const auto& [name, sd] = channels[c];
      const Eigen::VectorXd diff = on.channel(name) - off.channel(name);
      const double mean_square = diff.squaredNorm() / kSignalGrid;
      const double rms = std::sqrt(mean_square) / sd;
      signal.chi2 += samples * mean_square / (sd * sd);
      if (rms > signal.rms) {
        signal.rms = rms;
        signal.experiment = e.label;
        signal.channel = name;
      }
      const int row = (2 * static_cast<int>(a) + c) * kSignalGrid;
      const auto channel = std::find(off.channels.begin(), off.channels.end(), name) - off.channels.begin();
      difference.segment(row, kSignalGrid) = diff * (per_average / sd);
      for (int j = 0; j < k; ++j)
        sensitivity.block(row, j, kSignalGrid, 1) = d_outputs[channel].col(j) * (scale[j] * per_average / sd);
    }
  }
  // The priors as rows (a shift of the stroke zero costs its prior), then the baseline's best step.
  for (int j = 0; j < k; ++j) sensitivity(blocks * kSignalGrid + j, j) = prior_weight[j];
  const Eigen::VectorXd step = sensitivity.colPivHouseholderQr().solve(difference);
  const Eigen::VectorXd left = difference - sensitivity * step;
  for (int b = 0; b < blocks; ++b) {
    const double rms = std::sqrt(left.segment(b * kSignalGrid, kSignalGrid).squaredNorm() / kSignalGrid) / per_average;
    if (rms > signal.left_rms) {
      signal.left_rms = rms;
      signal.left_experiment = matrix[b / 2].label;
      signal.left_channel = channels[b % 2].first;
    }
  }
  return signal;
}

}  // namespace strut::sim
