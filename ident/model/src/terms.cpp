// The physics terms of the damper models (method.md, paper eqs. 21-24) and the catalogue that
// compositions are built from. Adding a term: a class here and one row in Catalogue().
#include "strut/ident/catalogue.h"

#include <cmath>
#include <numbers>
#include <utility>

namespace strut::ident {
namespace {


// Gas pressure as a model state: an algebraic unknown whose equation is the gas law. Keeping p as
// an unknown lets terms that make the law implicit (solubility, compliance) stay local.
const StateSpec kPressureState{"pressure", "Pa", 0, 7.0e5, 1e-3, 1e-3};
// Gas temperature: first-order state of the heat balance.
const StateSpec kTemperatureState{"temperature", "K", 1, 293.15, 1e-6, 1e-6};

constexpr double kAmbientK = 293.15;

// Physical ranges of the parameters (ParameterSpec::range).
constexpr PhysicalRange kPositive = PhysicalRange::Positive();
constexpr PhysicalRange kNonNegative = PhysicalRange::NonNegative();
constexpr PhysicalRange kNegative = PhysicalRange::Negative();

//! theta1 (q'' + theta2): moving mass under gravity.
class Inertia final : public Term {
 public:
  unsigned phases() const override { return kBalancePhase; }
  std::string_view name() const override { return "inertia"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({.index = 1, .name = "moving_mass", .unit = "kg", .default_value = 40.0,
                     .description = "mass moving with the stroke (piston, axle, fixture)", .estimate_by_default = true, .range = kPositive});
    b.add_parameter({.index = 2, .name = "gravity", .unit = "m/s^2", .default_value = 9.81,
                     .description = "gravitational acceleration (0: a horizontal rig)", .range = kNonNegative});
  }
  void Bind(const ModelBuilder& b) override {
    mass_ = b.parameter_position(1);
    gravity_ = b.parameter_position(2);
  }
  template <class S>
  void Eval(TermContext<S>& c) const {
    if (c.phase != TermContext<S>::Phase::kBalance) return;
    c.force += c.theta[mass_] * (c.v->stroke_accel + c.theta[gravity_]);
  }
  STRUT_TERM_EVALUATE

 private:
  int mass_ = -1, gravity_ = -1;
};

//! theta4 p: gas force on the piston.
class GasForce final : public Term {
 public:
  unsigned phases() const override { return kBalancePhase; }
  std::string_view name() const override { return "gas-force"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({.index = 4, .name = "gas_area", .unit = "m^2", .default_value = 5.0e-3,
                     .description = "pneumatic piston area", .estimate_by_default = true, .range = kPositive});
  }
  void Bind(const ModelBuilder& b) override {
    area_ = b.parameter_position(4);
    pressure_ = b.state_position("pressure", name());
  }
  template <class S>
  void Eval(TermContext<S>& c) const {
    if (c.phase != TermContext<S>::Phase::kBalance) return;
    c.force += c.theta[area_] * c.v->states[pressure_];
  }
  STRUT_TERM_EVALUATE

 private:
  int area_ = -1, pressure_ = -1;
};

//! theta3 q'|q'|: orifice damping.
class QuadraticDamping final : public Term {
 public:
  unsigned phases() const override { return kBalancePhase; }
  std::string_view name() const override { return "quadratic-damping"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({.index = 3, .name = "orifice_damping", .unit = "N s^2/m^2", .default_value = 8.0e3,
                     .description = "quadratic (orifice) damping coefficient", .estimate_by_default = true, .range = kNonNegative});
  }
  void Bind(const ModelBuilder& b) override { damping_ = b.parameter_position(3); }
  template <class S>
  void Eval(TermContext<S>& c) const {
    if (c.phase != TermContext<S>::Phase::kBalance) return;
    const S& v = c.v->stroke_rate;
    c.force += c.theta[damping_] * v * Abs(v);
  }
  STRUT_TERM_EVALUATE

 private:
  int damping_ = -1;
};

//! (theta8 + theta9 p) atan(theta10 q'): seal friction growing with pressure, smoothed by atan.
class PressureFriction final : public Term {
 public:
  unsigned phases() const override { return kBalancePhase; }
  std::string_view name() const override { return "pressure-friction"; }
  void Declare(ModelBuilder& b) override {
    // theta8 has no sign of its own: the amplitude theta8 + theta9 p is what must not be negative,
    // and p is an absolute pressure, never near 0.
    b.add_parameter({.index = 8, .name = "friction_base", .unit = "N", .default_value = 190.0,
                     .description = "pressure-independent friction amplitude", .estimate_by_default = true});
    b.add_parameter({.index = 9, .name = "friction_pressure", .unit = "m^2", .default_value = 4.8e-5,
                     .description = "friction amplitude per unit gas pressure", .estimate_by_default = true, .range = kNonNegative});
    b.add_parameter({.index = 10, .name = "friction_sharpness", .unit = "s/m", .default_value = 2000.0,
                     .description = "arctan sharpness of friction in stroke rate", .estimate_by_default = true, .range = kNonNegative});
  }
  void Bind(const ModelBuilder& b) override {
    base_ = b.parameter_position(8);
    per_pressure_ = b.parameter_position(9);
    sharpness_ = b.parameter_position(10);
    pressure_ = b.state_position("pressure", name());
  }
  template <class S>
  void Eval(TermContext<S>& c) const {
    if (c.phase != TermContext<S>::Phase::kBalance) return;
    const S amplitude = c.theta[base_] + c.theta[per_pressure_] * c.v->states[pressure_];
    c.force += amplitude * Atan(S(c.theta[sharpness_] * c.v->stroke_rate));
  }
  STRUT_TERM_EVALUATE

 private:
  int base_ = -1, per_pressure_ = -1, sharpness_ = -1, pressure_ = -1;
};

//! A constant force in the force balance, one parameter of its own.
class ConstantForce : public Term {
 public:
  unsigned phases() const override { return kBalancePhase; }
  void Declare(ModelBuilder& b) override { b.add_parameter(spec_); }
  void Bind(const ModelBuilder& b) override { position_ = b.parameter_position(spec_.index); }
  template <class S>
  void Eval(TermContext<S>& c) const {
    if (c.phase == TermContext<S>::Phase::kBalance) c.force += c.theta[position_];
  }
  STRUT_TERM_EVALUATE

 protected:
  explicit ConstantForce(ParameterSpec spec) : spec_(std::move(spec)) {}

 private:
  ParameterSpec spec_;
  int position_ = -1;
};

//! theta11: constant force on the piston (the atmosphere's pressure on its area).
class ForceOffset final : public ConstantForce {
 public:
  ForceOffset()
      : ConstantForce({.index = 11, .name = "force_offset", .unit = "N", .default_value = -507.0,
                       .description = "constant force on the piston (-p_atm A and the fixture's constant forces)",
                       .estimate_by_default = true}) {}
  std::string_view name() const override { return "force-offset"; }
};

//! theta39: the load cell's zero, force reading = true force + theta39. It sits in the force balance
//! only: theta11 also does work on the gas in the heat balance (the atmosphere on the piston), a
//! transducer's zero does none, so a zero folded into theta11 is shared with the weight theta1 g.
class LoadCellZero final : public ConstantForce {
 public:
  LoadCellZero()
      : ConstantForce({.index = 39, .name = "load_cell_zero", .unit = "N", .default_value = 0.0,
                       .description = "load-cell zero: force reading = true force + zero", .estimate_by_default = true,
                       .typical = 100.0, .prior_sd = kLoadCellZeroPriorSd}) {}
  std::string_view name() const override { return "load-cell-zero"; }
};

//! theta12: stroke sensor offset, y = q + theta12. Used by Model for inputs and outputs.
class StrokeOffset final : public Term {
 public:
  unsigned phases() const override { return 0; }
  std::string_view name() const override { return "stroke-offset"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({.index = 12, .name = "stroke_offset", .unit = "m", .default_value = 0.0,
                     .description = "stroke sensor offset: measured = true + offset", .estimate_by_default = true,
                     .typical = 1e-3, .prior_sd = kStrokeZeroPriorSd});
    b.set_output_offset(12);
  }
  void Bind(const ModelBuilder&) override {}
  template <class S>
  void Eval(TermContext<S>&) const {}
  STRUT_TERM_EVALUATE
};

//! 1 + theta6 q: gas volume relative to full extension (theta6 = -A/V0).
class GasVolume final : public Term {
 public:
  unsigned phases() const override { return kGasStatePhase; }
  std::string_view name() const override { return "gas-volume"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({.index = 6, .name = "volume_per_stroke", .unit = "1/m", .default_value = -1.0 / 0.3,
                     .description = "relative gas-volume change per stroke, -A/V0", .estimate_by_default = true,
                     .range = kNegative});
  }
  void Bind(const ModelBuilder& b) override { per_stroke_ = b.parameter_position(6); }
  template <class S>
  void Eval(TermContext<S>& c) const {
    if (c.phase == TermContext<S>::Phase::kGasState) c.gas_volume += 1.0 + c.theta[per_stroke_] * c.v->stroke;
  }
  STRUT_TERM_EVALUATE

 private:
  int per_stroke_ = -1;
};

//! 1 dof gas law p = theta5 (N/V)^theta7 (eq. 22; N = 1 without further terms).
class PolytropicGas final : public Term {
 public:
  unsigned phases() const override { return kGasStatePhase | kGasLawPhase; }
  std::string_view name() const override { return "polytropic-gas"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({.index = 5, .name = "extended_pressure", .unit = "Pa", .default_value = 7.0e5,
                     .description = "absolute gas pressure at full extension", .estimate_by_default = true, .range = kPositive});
    // Between 1 (isothermal) and 1.4 (adiabatic) for a perfect gas; a fit of a gas that dissolves
    // or exchanges heat may leave that band, so only the sign is physical.
    b.add_parameter({.index = 7, .name = "polytropic_exponent", .unit = "-", .default_value = 1.2,
                     .description = "polytropic exponent of the gas", .estimate_by_default = true, .range = kPositive});
    b.add_state(kPressureState);
  }
  void Bind(const ModelBuilder& b) override {
    p0_ = b.parameter_position(5);
    exponent_ = b.parameter_position(7);
    pressure_ = b.state_position("pressure", name());
  }
  template <class S>
  void Eval(TermContext<S>& c) const {
    using Phase = typename TermContext<S>::Phase;
    if (c.phase == Phase::kGasState) {
      c.gas_amount += 1.0;
    } else if (c.phase == Phase::kGasLaw) {
      c.state_residuals[pressure_] =
          c.v->states[pressure_] - c.theta[p0_] * Pow(S(c.gas_amount / c.gas_volume), c.theta[exponent_]);
    }
  }
  STRUT_TERM_EVALUATE

 private:
  int p0_ = -1, exponent_ = -1, pressure_ = -1;
};

//! 2 dof thermal gas (eqs. 23, 24): ideal gas p V = theta5 N T with a heat balance
//! theta15 T' + theta16 (1 + theta6 q)(T + theta17) - (theta4 p + theta11) q' = 0.
//! Replaces the polytropic law.
class HeatExchange final : public Term {
 public:
  unsigned phases() const override { return kGasStatePhase | kGasLawPhase | kBalancePhase; }
  std::string_view name() const override { return "heat-exchange"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({.index = 5, .name = "pressure_per_temperature", .unit = "Pa/K",
                     .default_value = 7.0e5 * (1.0 + 2.0e-5 * kAmbientK) / kAmbientK,
                     .description = "gas pressure per temperature at full extension (m R / V0)", .estimate_by_default = true, .range = kPositive});
    b.add_parameter({.index = 15, .name = "gas_heat_capacity", .unit = "J/K", .default_value = 17.9,
                     .description = "effective heat capacity of the gas", .estimate_by_default = true, .range = kPositive});
    b.add_parameter({.index = 16, .name = "wall_heat_conductance", .unit = "W/K", .default_value = 2.24,
                     .description = "heat conductance through the wall at full extension (0: adiabatic)",
                     .estimate_by_default = true, .sizes_term = true, .range = kNonNegative});
    b.add_parameter({.index = 17, .name = "minus_ambient_temperature", .unit = "K", .default_value = -kAmbientK,
                     .description = "minus the ambient (wall) temperature", .range = kNegative});
    b.add_state(kPressureState);
    b.add_state(kTemperatureState);
  }
  void Bind(const ModelBuilder& b) override {
    scale_ = b.parameter_position(5);
    capacity_ = b.parameter_position(15);
    conductance_ = b.parameter_position(16);
    minus_ambient_ = b.parameter_position(17);
    per_stroke_ = b.parameter_position(6);
    area_ = b.parameter_position(4);
    offset_ = b.has_term("force-offset") ? b.parameter_position(11) : -1;
    pressure_ = b.state_position("pressure", name());
    temperature_ = b.state_position("temperature", name());
  }
  template <class S>
  void Eval(TermContext<S>& c) const {
    using Phase = typename TermContext<S>::Phase;
    const auto& v = *c.v;
    const S& p = v.states[pressure_];
    const S& T = v.states[temperature_];
    if (c.phase == Phase::kGasState) {
      c.gas_amount += 1.0;
    } else if (c.phase == Phase::kGasLaw) {
      c.state_residuals[pressure_] = p - c.theta[scale_] * T * c.gas_amount / c.gas_volume;
    } else {
      S work_force = c.theta[area_] * p;
      if (offset_ >= 0) work_force += c.theta[offset_];
      c.state_residuals[temperature_] =
          c.theta[capacity_] * v.state_rates[temperature_] +
          c.theta[conductance_] * (1.0 + c.theta[per_stroke_] * v.stroke) * (T + c.theta[minus_ambient_]) -
          work_force * v.stroke_rate;
    }
  }
  STRUT_TERM_EVALUATE

 private:
  int scale_ = -1, capacity_ = -1, conductance_ = -1, minus_ambient_ = -1, per_stroke_ = -1, area_ = -1,
      offset_ = -1, pressure_ = -1, temperature_ = -1;
};

//! The paper's linear gas 'solubility' (eq. 24): p = theta5 T / (1 + theta6 q + theta7 T),
//! i.e. the free gas falls linearly with pressure: N = 1 - theta7 p / theta5.
class GasSolubility final : public Term {
 public:
  unsigned phases() const override { return kGasStatePhase; }
  std::string_view name() const override { return "gas-solubility"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({.index = 7, .name = "gas_solubility", .unit = "1/K", .default_value = 2.0e-5,
                     .description = "linear gas solubility coefficient (0: none)", .sizes_term = true,
                     .range = kNonNegative});
  }
  void Bind(const ModelBuilder& b) override {
    if (!b.has_term("heat-exchange"))
      throw ModelError("gas-solubility needs heat-exchange in the model (the paper's solubility is written "
                       "with the gas temperature); use 2dof or 1dof+heat-exchange+gas-solubility");
    solubility_ = b.parameter_position(7);
    scale_ = b.parameter_position(5);
    pressure_ = b.state_position("pressure", name());
  }
  template <class S>
  void Eval(TermContext<S>& c) const {
    if (c.phase == TermContext<S>::Phase::kGasState)
      c.gas_amount -= c.theta[solubility_] * c.v->states[pressure_] / c.theta[scale_];
  }
  STRUT_TERM_EVALUATE

 private:
  int solubility_ = -1, scale_ = -1, pressure_ = -1;
};

// ---------------------------------------------------------------------------------------------
// Extra physics for the simulated rig (damper-physics.md §2; docs/simulated-rig.md). Each term is
// smooth in every unknown so that Newton and IDA see a well-behaved Jacobian.

//! log(1 + e^x) without overflow; smooth max(0, x).
template <class S>
S Softplus(const S& x) {
  using std::exp;
  using std::log;
  if (Value(x) > 0.0) return S(x + log(1.0 + exp(S(-x))));
  return S(log(1.0 + exp(x)));
}

//! theta18 q': linear (viscous) damping of the seals and laminar flow.
class ViscousDamping final : public Term {
 public:
  unsigned phases() const override { return kBalancePhase; }
  std::string_view name() const override { return "viscous-damping"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({.index = 18, .name = "viscous_damping", .unit = "N s/m", .default_value = 300.0,
                     .description = "linear (viscous) damping of seals and laminar flow (0: none)", .sizes_term = true,
                     .range = kNonNegative});
  }
  void Bind(const ModelBuilder& b) override { damping_ = b.parameter_position(18); }
  template <class S>
  void Eval(TermContext<S>& c) const {
    if (c.phase == TermContext<S>::Phase::kBalance) c.force += c.theta[damping_] * c.v->stroke_rate;
  }
  STRUT_TERM_EVALUATE

 private:
  int damping_ = -1;
};

//! theta19 (theta8 + theta9 p) atan(theta10 q') exp(-(q'/theta20)^2): the Stribeck rise of the
//! seal friction at low speed. With the Coulomb level F_C = (theta8 + theta9 p) pi/2 of
//! pressure-friction the friction reads F_C sgn(q') [1 + theta19 exp(-(q'/theta20)^2)]
//! (sgn smoothed by atan), i.e. theta19 = F_S / F_C - 1 (damper-physics.md §2.8).
class StribeckFriction final : public Term {
 public:
  unsigned phases() const override { return kBalancePhase; }
  std::string_view name() const override { return "stribeck-friction"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({.index = 19, .name = "stribeck_excess", .unit = "-", .default_value = 0.25,
                     .description = "static over kinetic friction minus one, F_S / F_C - 1 (0: none)", .typical = 0.1,
                     .sizes_term = true, .range = kNonNegative});
    b.add_parameter({.index = 20, .name = "stribeck_velocity", .unit = "m/s", .default_value = 3.0e-3,
                     .description = "Stribeck velocity: width of the static-friction rise", .typical = 3.0e-3,
                     .shapes_term = true, .range = kPositive});
  }
  void Bind(const ModelBuilder& b) override {
    if (!b.has_term("pressure-friction"))
      throw ModelError("stribeck-friction scales the friction of pressure-friction, which the model lacks");
    excess_ = b.parameter_position(19);
    velocity_ = b.parameter_position(20);
    base_ = b.parameter_position(8);
    per_pressure_ = b.parameter_position(9);
    sharpness_ = b.parameter_position(10);
    pressure_ = b.state_position("pressure", name());
  }
  template <class S>
  void Eval(TermContext<S>& c) const {
    using std::exp;
    if (c.phase != TermContext<S>::Phase::kBalance) return;
    const S& v = c.v->stroke_rate;
    const S ratio = v / c.theta[velocity_];
    const S amplitude = c.theta[base_] + c.theta[per_pressure_] * c.v->states[pressure_];
    c.force += c.theta[excess_] * amplitude * Atan(S(c.theta[sharpness_] * v)) * S(exp(S(-ratio * ratio)));
  }
  STRUT_TERM_EVALUATE

 private:
  int excess_ = -1, velocity_ = -1, base_ = -1, per_pressure_ = -1, sharpness_ = -1, pressure_ = -1;
};

//! Top-out end stop near full extension (Hunt-Crossley contact, smoothed): penetration
//! d = theta24 softplus((theta23 - q) / theta24), contact force k d (1 + alpha (-q')) pushing
//! towards compression, so the balance gets -theta21 d (1 - theta22 q'). The Hunt-Crossley damping
//! is theta22 times the stiffness, so theta21 = 0 is no stop at all and the force is linear in it.
//! A distance s inside the stop position leaves k theta24 exp(-s / theta24): 0.02 N at 10 theta24
//! (damper-physics.md §2.9).
class EndStop final : public Term {
 public:
  unsigned phases() const override { return kBalancePhase; }
  std::string_view name() const override { return "end-stop"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({.index = 21, .name = "end_stop_stiffness", .unit = "N/m", .default_value = 5.0e6,
                     .description = "top-out stop contact stiffness, elastomer snubber (0: no stop)", .typical = 1.0e6,
                     .sizes_term = true, .range = kNonNegative});
    b.add_parameter({.index = 22, .name = "end_stop_dissipation", .unit = "s/m", .default_value = 2.0,
                     .description = "top-out stop Hunt-Crossley damping over stiffness (restitution)",
                     .range = kNonNegative});
    b.add_parameter({.index = 23, .name = "end_stop_position", .unit = "m", .default_value = 0.0,
                     .description = "stroke below which the top-out stop is in contact", .typical = 5.0e-3,
                     .shapes_term = true});
    b.add_parameter({.index = 24, .name = "end_stop_smoothing", .unit = "m", .default_value = 1.0e-4,
                     .description = "length over which the contact onset is smoothed", .range = kPositive});
  }
  void Bind(const ModelBuilder& b) override {
    stiffness_ = b.parameter_position(21);
    dissipation_ = b.parameter_position(22);
    position_ = b.parameter_position(23);
    smoothing_ = b.parameter_position(24);
  }
  template <class S>
  void Eval(TermContext<S>& c) const {
    if (c.phase != TermContext<S>::Phase::kBalance) return;
    const S& w = c.theta[smoothing_];
    const S penetration = w * Softplus(S((c.theta[position_] - c.v->stroke) / w));
    c.force -= c.theta[stiffness_] * penetration * (1.0 - c.theta[dissipation_] * c.v->stroke_rate);
  }
  STRUT_TERM_EVALUATE

 private:
  int stiffness_ = -1, dissipation_ = -1, position_ = -1, smoothing_ = -1;
};

//! Oil and cylinder compliance: the oil shrinks and the cylinder swells with pressure, giving the
//! gas more room: V_g / V0 += theta25 theta26 (p - theta27), with theta25 = V_oil / V0 and
//! theta26 the effective compliance of oil and cylinder, 1/K_eff = 1/K_oil + D/(E t)
//! (damper-physics.md §2.3). Softens the gas spring at deep compression. Sized by the compliance,
//! not the bulk modulus: 0 is rigid oil and the volume is linear in it.
class OilCompressibility final : public Term {
 public:
  unsigned phases() const override { return kGasStatePhase; }
  std::string_view name() const override { return "oil-compressibility"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({.index = 25, .name = "oil_volume_ratio", .unit = "-", .default_value = 1.0,
                     .description = "oil volume over the gas volume at full extension, V_oil / V0",
                     .range = kNonNegative});
    b.add_parameter({.index = 26, .name = "oil_compliance", .unit = "1/Pa", .default_value = 1.0 / 1.2e9,
                     .description = "effective compliance of oil and cylinder, 1/K_eff (0: rigid)", .typical = 1.0e-9,
                     .sizes_term = true, .range = kNonNegative});
    b.add_parameter({.index = 27, .name = "compliance_reference_pressure", .unit = "Pa", .default_value = 7.0e5,
                     .description = "pressure at which the compliance adds no volume (the charge pressure)",
                     .range = kPositive});
  }
  void Bind(const ModelBuilder& b) override {
    ratio_ = b.parameter_position(25);
    compliance_ = b.parameter_position(26);
    reference_ = b.parameter_position(27);
    pressure_ = b.state_position("pressure", name());
  }
  template <class S>
  void Eval(TermContext<S>& c) const {
    if (c.phase == TermContext<S>::Phase::kGasState)
      c.gas_volume += c.theta[ratio_] * c.theta[compliance_] * (c.v->states[pressure_] - c.theta[reference_]);
  }
  STRUT_TERM_EVALUATE

 private:
  int ratio_ = -1, compliance_ = -1, reference_ = -1, pressure_ = -1;
};

//! Real-gas nitrogen: the ideal-gas pressure times the compressibility factor
//! Z = 1 + theta31 (B(T) rho + theta30 rho^2), B(T) = theta28 - theta29 / T (a two-constant fit of the N2
//! second virial coefficient, damper-physics.md §2.10), rho the molar density of the free gas:
//! theta5 N / (R V) in 2 dof (theta5 = n R / V0), theta5 N / (R T_amb V) in 1 dof (theta5 the
//! charge pressure; the 1 dof model has no gas temperature, B is taken at ambient). It multiplies
//! the free gas amount by Z (by Z^(1/theta7) under the polytropic law), so every gas law gets p Z.
//! The gain theta31 sizes the correction: 0 is the ideal gas, 1 nitrogen.
class RealGas final : public Term {
 public:
  unsigned phases() const override { return kGasStatePhase; }
  std::string_view name() const override { return "real-gas"; }
  void Declare(ModelBuilder& b) override {
    // The coefficients shape Z - 1 (they are N2's, any sign a gas may have); theta31 sizes it.
    b.add_parameter({.index = 28, .name = "virial_b0", .unit = "m^3/mol", .default_value = 4.88e-5,
                     .description = "N2 second virial coefficient B(T) = b0 - a / T: b0"});
    b.add_parameter({.index = 29, .name = "virial_a", .unit = "m^3 K/mol", .default_value = 1.59e-2,
                     .description = "N2 second virial coefficient B(T) = b0 - a / T: a"});
    b.add_parameter({.index = 30, .name = "virial_c", .unit = "m^6/mol^2", .default_value = 1.4e-9,
                     .description = "N2 third virial coefficient C"});
    b.add_parameter({.index = 31, .name = "virial_gain", .unit = "-", .default_value = 1.0,
                     .description = "gain on the virial correction Z - 1 (0: ideal gas, 1: nitrogen)", .typical = 1.0,
                     .sizes_term = true, .range = kNonNegative});
  }
  void Bind(const ModelBuilder& b) override {
    b0_ = b.parameter_position(28);
    a_ = b.parameter_position(29);
    c_ = b.parameter_position(30);
    gain_ = b.parameter_position(31);
    scale_ = b.parameter_position(5);
    thermal_ = b.has_term("heat-exchange");
    exponent_ = thermal_ ? -1 : b.parameter_position(7);
    temperature_ = thermal_ ? b.state_position("temperature", name()) : -1;
    if (!thermal_ && !b.has_term("polytropic-gas"))
      throw ModelError("real-gas needs a gas law (polytropic-gas or heat-exchange)");
  }
  template <class S>
  void Eval(TermContext<S>& c) const {
    using std::exp;
    using std::log;
    if (c.phase != TermContext<S>::Phase::kGasState) return;
    constexpr double kGasConstant = 8.314462618;  // J/(mol K)
    S rho, b;
    if (thermal_) {
      const S& T = c.v->states[temperature_];
      rho = c.theta[scale_] * c.gas_amount / (kGasConstant * c.gas_volume);
      b = c.theta[b0_] - c.theta[a_] / T;
    } else {
      rho = c.theta[scale_] * c.gas_amount / (kGasConstant * kAmbientK * c.gas_volume);
      b = c.theta[b0_] - c.theta[a_] / kAmbientK;
    }
    const S z = 1.0 + c.theta[gain_] * (b * rho + c.theta[c_] * rho * rho);
    if (thermal_)
      c.gas_amount *= z;
    else
      c.gas_amount *= S(exp(S(log(z) / c.theta[exponent_])));
  }
  STRUT_TERM_EVALUATE

 private:
  int b0_ = -1, a_ = -1, c_ = -1, gain_ = -1, scale_ = -1, exponent_ = -1, temperature_ = -1;
  bool thermal_ = false;
};

// ---------------------------------------------------------------------------------------------
// Physics real dampers show beyond the paper's models (damper-physics.md §2.6-§2.8, §2.1, §2.4).
// Each is sized by one parameter that is 0 where the effect is absent, and smooth enough in every
// unknown for Newton (continuous first derivatives).

//! Recoil (extension) damping above compression: a snubber or flapper valve closes part of the
//! orifice in extension, so c_ext = (1 + theta32) theta3. The extra force acts only when the
//! stroke rate is negative (extension): theta32 theta3 q'|q'| for q' < 0, i.e. -theta32 theta3 q'^2
//! there and 0 in compression (its derivative is continuous at the reversal). damper-physics.md
//! §2.6: c_ext = (2-5) c_comp, so theta32 = 1-4.
class RecoilDamping final : public Term {
 public:
  unsigned phases() const override { return kBalancePhase; }
  std::string_view name() const override { return "recoil-damping"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({.index = 32, .name = "recoil_damping_excess", .unit = "-", .default_value = 1.5,
                     .description = "extension over compression orifice damping minus one, c_ext / c_comp - 1 (0: none)",
                     .typical = 1.0, .sizes_term = true, .range = kNonNegative});
  }
  void Bind(const ModelBuilder& b) override {
    if (!b.has_term("quadratic-damping"))
      throw ModelError("recoil-damping scales the orifice damping of quadratic-damping, which the model lacks");
    excess_ = b.parameter_position(32);
    damping_ = b.parameter_position(3);
  }
  template <class S>
  void Eval(TermContext<S>& c) const {
    if (c.phase != TermContext<S>::Phase::kBalance) return;
    const S& v = c.v->stroke_rate;
    if (Value(v) < 0.0) c.force -= c.theta[excess_] * c.theta[damping_] * v * v;
  }
  STRUT_TERM_EVALUATE

 private:
  int excess_ = -1, damping_ = -1;
};

//! A metering pin: the orifice's net area shrinks as the pin enters it, so the orifice damping grows
//! with the stroke, c(q) = theta3 (1 + theta33 q), adding theta33 theta3 q q'|q'|. A 30-70 % area
//! reduction over the 0.264 m stroke (damper-physics.md §2.7) raises c 2-11 times, theta33 = 4-40 1/m;
//! a pin that opens the orifice deeper in the stroke is not a metering pin, so theta33 >= 0.
class MeteringPin final : public Term {
 public:
  unsigned phases() const override { return kBalancePhase; }
  std::string_view name() const override { return "metering-pin"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({.index = 33, .name = "metering_pin_gradient", .unit = "1/m", .default_value = 3.9,
                     .description = "relative growth of the orifice damping per stroke, (c(q) / c(0) - 1) / q (0: no pin)",
                     .typical = 4.0, .sizes_term = true, .range = kNonNegative});
  }
  void Bind(const ModelBuilder& b) override {
    if (!b.has_term("quadratic-damping"))
      throw ModelError("metering-pin varies the orifice damping of quadratic-damping, which the model lacks");
    gradient_ = b.parameter_position(33);
    damping_ = b.parameter_position(3);
  }
  template <class S>
  void Eval(TermContext<S>& c) const {
    if (c.phase != TermContext<S>::Phase::kBalance) return;
    const S& v = c.v->stroke_rate;
    c.force += c.theta[gradient_] * c.theta[damping_] * c.v->stroke * v * Abs(v);
  }
  STRUT_TERM_EVALUATE

 private:
  int gradient_ = -1, damping_ = -1;
};

//! Seal friction that differs between compression and extension (damper-physics.md §2.8: 10-30 %):
//! the friction of pressure-friction times 1 + theta34 sgn(q'), with sgn smoothed as the friction
//! itself is, so the extra force is theta34 (theta8 + theta9 p) (2/pi) atan(theta10 q')^2 (even in
//! the rate; (2/pi) atan^2 tends to |atan|). |theta34| < 1 keeps the friction opposing the motion
//! in both directions; positive: more friction in compression.
class FrictionAsymmetry final : public Term {
 public:
  unsigned phases() const override { return kBalancePhase; }
  std::string_view name() const override { return "friction-asymmetry"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({.index = 34, .name = "friction_asymmetry", .unit = "-", .default_value = 0.2,
                     .description = "relative excess of compression over extension friction (0: symmetric)",
                     .typical = 0.1, .sizes_term = true, .range = {-1.0, 1.0, true, true}});
  }
  void Bind(const ModelBuilder& b) override {
    if (!b.has_term("pressure-friction"))
      throw ModelError("friction-asymmetry scales the friction of pressure-friction, which the model lacks");
    asymmetry_ = b.parameter_position(34);
    base_ = b.parameter_position(8);
    per_pressure_ = b.parameter_position(9);
    sharpness_ = b.parameter_position(10);
    pressure_ = b.state_position("pressure", name());
  }
  template <class S>
  void Eval(TermContext<S>& c) const {
    if (c.phase != TermContext<S>::Phase::kBalance) return;
    const S amplitude = c.theta[base_] + c.theta[per_pressure_] * c.v->states[pressure_];
    const S a = Atan(S(c.theta[sharpness_] * c.v->stroke_rate));
    c.force += c.theta[asymmetry_] * amplitude * (2.0 / std::numbers::pi) * a * a;
  }
  STRUT_TERM_EVALUATE

 private:
  int asymmetry_ = -1, base_ = -1, per_pressure_ = -1, sharpness_ = -1, pressure_ = -1;
};

//! Wall heat transfer that grows with pressure (natural convection, damper-physics.md §2.1:
//! h ∝ (p/T)^(2/3)): the wall conductance of heat-exchange times 1 + theta35 ((p / p_c)^(2/3) - 1),
//! p_c = theta5 T_amb the charge pressure of an ideal gas at ambient temperature. theta35 = 1 is the
//! convection law, 0 the paper's conductance. Evaluated after heat-exchange, to whose heat balance
//! it adds.
class PressureHeatTransfer final : public Term {
 public:
  unsigned phases() const override { return kBalancePhase; }
  std::string_view name() const override { return "pressure-heat-transfer"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({.index = 35, .name = "heat_transfer_pressure_gain", .unit = "-", .default_value = 1.0,
                     .description = "weight of the (p / p_charge)^(2/3) growth of the wall heat conductance (0: none)",
                     .typical = 1.0, .sizes_term = true, .range = kNonNegative});
  }
  void Bind(const ModelBuilder& b) override {
    if (!b.has_term("heat-exchange"))
      throw ModelError("pressure-heat-transfer varies the wall heat conductance of heat-exchange, which the model lacks");
    gain_ = b.parameter_position(35);
    scale_ = b.parameter_position(5);
    conductance_ = b.parameter_position(16);
    minus_ambient_ = b.parameter_position(17);
    per_stroke_ = b.parameter_position(6);
    pressure_ = b.state_position("pressure", name());
    temperature_ = b.state_position("temperature", name());
  }
  template <class S>
  void Eval(TermContext<S>& c) const {
    if (c.phase != TermContext<S>::Phase::kBalance) return;
    const auto& v = *c.v;
    const S charge = -c.theta[scale_] * c.theta[minus_ambient_];
    const S growth = Pow(S(v.states[pressure_] / charge), S(2.0 / 3.0)) - 1.0;
    c.state_residuals[temperature_] += c.theta[gain_] * growth * c.theta[conductance_] *
                                       (1.0 + c.theta[per_stroke_] * v.stroke) *
                                       (v.states[temperature_] + c.theta[minus_ambient_]);
  }
  STRUT_TERM_EVALUATE

 private:
  int gain_ = -1, scale_ = -1, conductance_ = -1, minus_ambient_ = -1, per_stroke_ = -1, pressure_ = -1,
      temperature_ = -1;
};

//! An isothermal dead volume on the pressure line (transducer cavity, fittings: damper-physics.md
//! §2.4), theta36 = V_d / V0. At the wall temperature it holds gas the main chamber lacks, more at
//! high pressure: the effective polytropic exponent falls at deep compression. With a gas
//! temperature (2 dof) the gas law sees the volume V0 (1 + theta6 q) + V_d (T / T_amb - 1) (the
//! dead volume at ambient temperature is part of V0); without one (the polytropic law, whose
//! theta5 is the charge pressure) the main chamber loses the gas the dead volume gains,
//! N -= theta36 (p / theta5 - 1).
class DeadVolume final : public Term {
 public:
  unsigned phases() const override { return kGasStatePhase; }
  std::string_view name() const override { return "dead-volume"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({.index = 36, .name = "dead_volume_ratio", .unit = "-", .default_value = 3.0e-3,
                     .description = "isothermal dead volume of the pressure line over the gas volume at full extension (0: none)",
                     .typical = 3.0e-3, .sizes_term = true, .range = kNonNegative});
  }
  void Bind(const ModelBuilder& b) override {
    ratio_ = b.parameter_position(36);
    scale_ = b.parameter_position(5);
    pressure_ = b.state_position("pressure", name());
    thermal_ = b.has_term("heat-exchange");
    if (thermal_) {
      temperature_ = b.state_position("temperature", name());
      minus_ambient_ = b.parameter_position(17);
    } else if (!b.has_term("polytropic-gas")) {
      throw ModelError("dead-volume needs a gas law (polytropic-gas or heat-exchange)");
    }
  }
  template <class S>
  void Eval(TermContext<S>& c) const {
    if (c.phase != TermContext<S>::Phase::kGasState) return;
    if (thermal_)
      c.gas_volume -= c.theta[ratio_] * (c.v->states[temperature_] / c.theta[minus_ambient_] + 1.0);
    else
      c.gas_amount -= c.theta[ratio_] * (c.v->states[pressure_] / c.theta[scale_] - 1.0);
  }
  STRUT_TERM_EVALUATE

 private:
  int ratio_ = -1, scale_ = -1, pressure_ = -1, temperature_ = -1, minus_ambient_ = -1;
  bool thermal_ = false;
};

//! theta37 theta38: gas lost through the seals over the session, linear in when the experiment was
//! recorded (theta38, its fraction of the session, set per experiment by the fit): the free gas is
//! 1 - theta37 theta38 of the charge, so theta37 is the fraction lost by the last experiment.
class ChargeLoss final : public Term {
 public:
  unsigned phases() const override { return kGasStatePhase; }
  std::string_view name() const override { return "charge-loss"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({.index = 37, .name = "charge_lost", .unit = "-", .default_value = 0.01,
                     .description = "fraction of the gas charge lost between the session's first and last experiment (0: none)",
                     .typical = 0.01, .sizes_term = true, .range = {0.0, 1.0, false, true}});
    b.add_parameter({.index = kSessionTimeIndex, .name = "session_time", .unit = "-", .default_value = 0.0,
                     .description = "when the experiment was recorded, as a fraction of the session (set from the recording)",
                     .typical = 1.0, .range = {0.0, 1.0, false, false}, .experiment_condition = true});
  }
  void Bind(const ModelBuilder& b) override {
    if (!b.has_term("polytropic-gas") && !b.has_term("heat-exchange"))
      throw ModelError("charge-loss needs a gas law (polytropic-gas or heat-exchange)");
    lost_ = b.parameter_position(37);
    time_ = b.parameter_position(kSessionTimeIndex);
  }
  template <class S>
  void Eval(TermContext<S>& c) const {
    if (c.phase == TermContext<S>::Phase::kGasState) c.gas_amount -= c.theta[lost_] * c.theta[time_];
  }
  STRUT_TERM_EVALUATE

 private:
  int lost_ = -1, time_ = -1;
};

// ---------------------------------------------------------------------------------------------
// The empirical discrepancy (docs/discovery.md): what no catalogue term explains, as a sparse sum of
// functions of the model's own states and inputs. Each function is scaled by a level of the model it
// is added to (the orifice damping theta3, the friction amplitude, the gas force per bar theta4 p_ref)
// so that its coefficient is dimensionless, 0 means absent and 1 is as large as that level. Discovery
// estimates only the coefficients it selects (the rest stay 0); `--model ...+discrepancy` estimates
// every one, each with a N(0, typical) prior.

namespace discrepancy {

constexpr double kStroke = 0.1;       // m: the stroke unit of the shapes (q / 0.1 m)
constexpr double kRate = 0.1;         // m/s: the rate at which the linear damping equals theta3 kRate^2
constexpr double kDirection = 2e-3;   // m/s: the width of the smoothed direction sgn(q')
constexpr double kPressure = 1e6;     // Pa: the gas force unit theta4 kPressure
constexpr double kLoopPressure = 1e7; // Pa: the pressure unit of the pressure-damping shape
// Pa: the heat-flow function's reference pressure, where it is 0 whatever its exponent: about the
// geometric middle of a strut's 0.5-10 MPa.
constexpr double kHeatFlowPressure = 2e6;
// m/s: the widths of the low-speed friction shapes, spread over the 1-10 mm/s a seal's Stribeck
// velocity spans (damper-physics.md §2.8), about twice apart: sums of neighbours take the widths
// between them.
constexpr double kLowSpeedNarrow = 2e-3;
constexpr double kLowSpeed = 4.5e-3;
constexpr double kLowSpeedWide = 1e-2;
constexpr double kContactLength = 1e-3;    // m: the contact force's unit of penetration
constexpr double kContactSmoothing = 1e-4; // m: the length over which the contact sets in

// The shapes a start tries: powers of the pressure; contact positions from 2 mm beyond full
// extension to 12 mm inside it, 0.5 mm apart.
std::vector<double> ExponentGrid() { return {0.25, 0.4, 0.55, 0.7, 0.85, 1.0, 1.25, 1.5, 2.0}; }
std::vector<double> ContactGrid() {
  std::vector<double> grid;
  for (int k = -4; k <= 24; ++k) grid.push_back(0.5e-3 * k);
  return grid;
}

enum class Shape {
  kDampingDirection,        // theta3 q'^2: even in the rate
  kDampingStroke,           // theta3 (q/L) q'|q'|
  kDampingStrokeDirection,  // theta3 (q/L) q'^2
  kDampingStrokeSquared,    // theta3 (q/L)^2 q'|q'|
  kViscous,                 // theta3 v_r q'
  kViscousDirection,        // theta3 v_r q' sgn(q')
  kDampingPressure,         // theta3 v_r q' p / p_r
  kFrictionDirection,       // F_f (2/pi) atan(theta10 q')^2
  kFrictionStroke,          // F_f atan(theta10 q') (q/L)
  kStiffnessSquared,        // theta4 p_u (q/L)^2
  kStiffnessCubed,          // theta4 p_u (q/L)^3
  kForceDrift,              // theta4 p_u s
  kVolumeSquared,           // gas volume + (q/L)^2
  kVolumeCubed,             // gas volume + (q/L)^3
  kGasPressure,             // free gas + p / p_r
  kGasDrift,                // free gas + s
  kForceStatic,             // theta4 p_u (z/L): z the experiment's static position
  kForceStaticSquared,      // theta4 p_u (z/L)^2
  kGasStatic,               // free gas + z/L
  kGasStaticSquared,        // free gas + (z/L)^2
  kVolumePressure,          // gas volume + p / p_r
  kConductancePressure,     // wall heat flow x ((p / p_r)^n - 1) / n, n the shape parameter
  kFrictionLowSpeed,        // F_f atan(theta10 q') exp(-(q'/v_1)^2)
  kFrictionLowSpeedWide,    // F_f atan(theta10 q') exp(-(q'/v_2)^2)
  kFrictionLowSpeedNarrow,  // F_f atan(theta10 q') exp(-(q'/v_0)^2)
  kContactTopOut,           // -theta4 p_u d / 1 mm, d = w softplus((z_c - q) / w), z_c the shape parameter
  kContactTopOutRate,       // -theta4 p_u (d / 1 mm)(-q' / 0.1 m/s): the contact's dissipation
  kGasPressureTemperature,  // free gas + (p / p_r)(T / T_amb - 1)
};

struct Function {
  Shape shape;
  DiscrepancyFunction public_part;
  const char* needs;  // the term whose level scales it
  const char* twin;   // a catalogue term it duplicates: left out beside it
  bool gas = false;   // acts on the gas state, not the force (or the heat balance)
};

const std::vector<Function>& Library() {
  static const std::vector<Function> functions = {
      {Shape::kDampingDirection, {70, "damping-direction", "theta3 q'^2 (orifice damping more in compression for c > 0, in extension for c < 0)", "recoil-damping", 0.5}, "quadratic-damping", "recoil-damping"},
      {Shape::kDampingStroke, {71, "damping-stroke", "theta3 (q / 0.1 m) q'|q'| (orifice damping growing with the stroke)", "metering-pin", 0.5}, "quadratic-damping", "metering-pin"},
      {Shape::kDampingStrokeDirection, {72, "damping-stroke-direction", "theta3 (q / 0.1 m) q'^2 (the direction asymmetry growing with the stroke)", "", 0.5}, "quadratic-damping", ""},
      {Shape::kDampingStrokeSquared, {73, "damping-stroke-squared", "theta3 (q / 0.1 m)^2 q'|q'| (orifice damping curving with the stroke)", "metering-pin", 0.5}, "quadratic-damping", ""},
      {Shape::kViscous, {74, "viscous", "theta3 (0.1 m/s) q' (damping linear in the rate)", "viscous-damping", 0.5}, "quadratic-damping", "viscous-damping"},
      {Shape::kViscousDirection, {75, "viscous-direction", "theta3 (0.1 m/s) |q'| (linear damping that differs with the direction)", "recoil-damping", 0.5}, "quadratic-damping", ""},
      {Shape::kDampingPressure, {76, "damping-pressure", "theta3 (0.1 m/s) q' p / 10 MPa (a loop growing with the pressure)", "pressure-heat-transfer", 0.5}, "quadratic-damping", ""},
      {Shape::kFrictionDirection, {77, "friction-direction", "(theta8 + theta9 p) (2/pi) atan(theta10 q')^2 (friction that differs with the direction)", "friction-asymmetry", 0.2}, "pressure-friction", "friction-asymmetry"},
      {Shape::kFrictionStroke, {78, "friction-stroke", "(theta8 + theta9 p) atan(theta10 q') (q / 0.1 m) (friction growing with the stroke)", "", 0.2}, "pressure-friction", ""},
      {Shape::kStiffnessSquared, {79, "stiffness-squared", "theta4 (1 MPa) (q / 0.1 m)^2 (a force growing with the stroke squared)", "dead-volume", 0.1}, "gas-force", ""},
      {Shape::kStiffnessCubed, {80, "stiffness-cubed", "theta4 (1 MPa) (q / 0.1 m)^3 (a force growing with the stroke cubed)", "dead-volume", 0.1}, "gas-force", ""},
      {Shape::kForceDrift, {81, "force-drift", "theta4 (1 MPa) s (a force level drifting with the recording time s)", "charge-loss", 0.01}, "gas-force", ""},
      {Shape::kVolumeSquared, {82, "volume-stroke-squared", "gas volume + (q / 0.1 m)^2 (a gas volume law curving with the stroke)", "dead-volume", 0.01}, "gas-volume", "", true},
      {Shape::kVolumeCubed, {83, "volume-stroke-cubed", "gas volume + (q / 0.1 m)^3", "dead-volume", 0.01}, "gas-volume", "", true},
      {Shape::kGasPressure, {84, "gas-pressure", "free gas + p / 10 MPa (free gas that changes with the pressure)", "gas-solubility", 0.01}, "gas-volume", "", true},
      {Shape::kGasDrift, {85, "gas-drift", "free gas + s (free gas that changes with the recording time s)", "charge-loss", 0.01}, "gas-volume", "charge-loss", true},
      // With the global levels (theta11, theta5) the static functions give each of three
      // static-position groups a level of its own.
      {Shape::kForceStatic, {86, "force-static-position", "theta4 (1 MPa) (z / 0.1 m) (a force level that changes with the experiment's static position z)", "", 0.01}, "gas-force", ""},
      {Shape::kForceStaticSquared, {87, "force-static-position-squared", "theta4 (1 MPa) (z / 0.1 m)^2 (a force level curving with the static position)", "", 0.01}, "gas-force", ""},
      {Shape::kGasStatic, {88, "gas-static-position", "free gas + z / 0.1 m (free gas that changes with the experiment's static position z)", "", 0.01}, "gas-volume", "", true},
      {Shape::kGasStaticSquared, {89, "gas-static-position-squared", "free gas + (z / 0.1 m)^2 (free gas curving with the static position)", "", 0.01}, "gas-volume", "", true},
      // A gas volume shrinking as the pressure rises is a gas stiffer than its law, as a real gas is.
      {Shape::kVolumePressure, {90, "volume-pressure", "gas volume + p / 10 MPa (a gas volume growing with the pressure: oil or cylinder that give way)", "oil-compressibility", 0.01, 0, {}, "real-gas"}, "gas-volume", "oil-compressibility", true},
      // The wall heat flow of heat-exchange, theta16 (1 + theta6 q)(T + theta17), times a power of
      // the pressure less its value at 2 MPa, the exponent theta92 its shape: a heat-transfer
      // correlation's form (h grows as a power of the gas density), whose exponent the data give.
      // A conductance falling as the pressure rises is no heat transfer's (it grows with the gas
      // density): on the thermal loop it acts as a gas whose pressure follows its temperature more
      // at high pressure, a real gas.
      {Shape::kConductancePressure, {91, "conductance-pressure", "wall heat flow x ((p / 2 MPa)^theta92 - 1) / theta92 (a wall heat conductance growing as a power of the pressure)", "pressure-heat-transfer", 1.0, 92, ExponentGrid(), "real-gas"}, "heat-exchange", "pressure-heat-transfer", true},
      {Shape::kFrictionLowSpeed, {93, "friction-low-speed", "(theta8 + theta9 p) atan(theta10 q') exp(-(q' / 4.5 mm/s)^2) (friction higher near the reversals than sliding)", "stribeck-friction", 0.2}, "pressure-friction", "stribeck-friction"},
      {Shape::kFrictionLowSpeedWide, {94, "friction-low-speed-wide", "(theta8 + theta9 p) atan(theta10 q') exp(-(q' / 10 mm/s)^2) (friction higher at low speed, over a wider band)", "stribeck-friction", 0.2}, "pressure-friction", "stribeck-friction"},
      {Shape::kFrictionLowSpeedNarrow, {95, "friction-low-speed-narrow", "(theta8 + theta9 p) atan(theta10 q') exp(-(q' / 2 mm/s)^2) (friction higher only just at the reversals)", "stribeck-friction", 0.2}, "pressure-friction", "stribeck-friction"},
      // A contact near full extension whose position theta97 the data give: a force toward
      // compression growing with the penetration past it.
      {Shape::kContactTopOut, {96, "contact-top-out", "-theta4 (1 MPa) d / 1 mm, d = 0.1 mm softplus((theta97 - q) / 0.1 mm) (a contact pushing toward compression past a stroke position)", "end-stop", 1.0, 97, ContactGrid()}, "gas-force", "end-stop"},
      {Shape::kContactTopOutRate, {98, "contact-top-out-rate", "-theta4 (1 MPa) (d / 1 mm) (-q' / 0.1 m/s), d as above (the contact's force growing with the rate of compression into it)", "end-stop", 1.0, 97, ContactGrid()}, "gas-force", "end-stop"},
      // A gas whose pressure follows its temperature more than the gas law holds, the more the
      // denser it is: a real gas's compressibility factor falls with the temperature at a given
      // density (its second virial coefficient), 0.2 on nitrogen at 293 K.
      {Shape::kGasPressureTemperature, {99, "gas-pressure-temperature", "free gas + (p / 10 MPa)(T / 293.15 K - 1) (a gas pressure that follows its temperature more at high pressure)", "real-gas", 0.2}, "heat-exchange", "real-gas", true},
  };
  return functions;
}

}  // namespace discrepancy

//! theta70..theta99: the empirical discrepancy, the library above. Functions whose level the model
//! lacks, or whose catalogue twin it has, are left out.
class Discrepancy final : public Term {
 public:
  unsigned phases() const override { return kBalancePhase | kGasStatePhase; }
  std::string_view name() const override { return "discrepancy"; }
  void Declare(ModelBuilder& b) override {
    bool contact = false;
    for (const discrepancy::Function& f : discrepancy::Library()) {
      if (!b.has_term(f.needs) || (*f.twin && b.has_term(f.twin))) continue;
      const DiscrepancyFunction& p = f.public_part;
      b.add_parameter({.index = p.index, .name = "discrepancy_" + p.name, .unit = "-", .default_value = 0.0,
                       .description = "empirical: " + p.shape, .estimate_by_default = true, .typical = p.typical,
                       .prior_sd = p.typical});
      used_.push_back({f.shape, -1});
      if (f.shape == discrepancy::Shape::kConductancePressure)
        b.add_parameter({.index = p.shape_index, .name = "discrepancy_conductance-pressure_exponent", .unit = "-",
                         .default_value = 1.0, .description = "empirical: the power of the pressure the wall heat conductance grows with",
                         .estimate_by_default = true, .typical = 0.5, .prior_sd = 0.5});
      // The contact's force and its rate part share the position.
      if ((f.shape == discrepancy::Shape::kContactTopOut || f.shape == discrepancy::Shape::kContactTopOutRate) &&
          !std::exchange(contact, true))
        b.add_parameter({.index = p.shape_index, .name = "discrepancy_contact-top-out_position", .unit = "m",
                         .default_value = 0.0, .description = "empirical: the stroke below which the contact pushes",
                         .estimate_by_default = true, .typical = 5e-3, .prior_sd = 5e-3});
      if (f.shape == discrepancy::Shape::kForceDrift || f.shape == discrepancy::Shape::kGasDrift) drift_ = true;
      if (IsStatic(f.shape)) static_ = true;
    }
    if (used_.empty()) throw ModelError("discrepancy needs a damper model (quadratic-damping, gas-force, gas-volume)");
    if (drift_)
      b.add_parameter({.index = kSessionTimeIndex, .name = "session_time", .unit = "-", .default_value = 0.0,
                       .description = "when the experiment was recorded, as a fraction of the session (set from the recording)",
                       .typical = 1.0, .range = {0.0, 1.0, false, false}, .experiment_condition = true});
    if (static_)
      b.add_parameter({.index = kStaticPositionIndex, .name = "static_position", .unit = "m", .default_value = 0.0,
                       .description = "the experiment's static stroke position (set from the recording)",
                       .typical = 0.1, .experiment_condition = true});
  }
  void Bind(const ModelBuilder& b) override {
    std::size_t k = 0;
    for (const discrepancy::Function& f : discrepancy::Library())
      if (k < used_.size() && used_[k].shape == f.shape) used_[k++].position = b.parameter_position(f.public_part.index);
    const auto position = [&](const char* term, int index) { return b.has_term(term) ? b.parameter_position(index) : -1; };
    damping_ = position("quadratic-damping", 3);
    friction_base_ = position("pressure-friction", 8);
    friction_pressure_ = position("pressure-friction", 9);
    sharpness_ = position("pressure-friction", 10);
    area_ = position("gas-force", 4);
    time_ = drift_ ? b.parameter_position(kSessionTimeIndex) : -1;
    static_position_ = static_ ? b.parameter_position(kStaticPositionIndex) : -1;
    pressure_ = b.has_state("pressure") ? b.state_position("pressure", name()) : -1;
    const auto uses = [&](discrepancy::Shape shape) {
      return std::any_of(used_.begin(), used_.end(), [&](const Used& u) { return u.shape == shape; });
    };
    if (uses(discrepancy::Shape::kConductancePressure)) {
      exponent_ = b.parameter_position(92);
      conductance_ = b.parameter_position(16);
      per_stroke_ = b.parameter_position(6);
      minus_ambient_ = b.parameter_position(17);
    }
    if (uses(discrepancy::Shape::kConductancePressure) || uses(discrepancy::Shape::kGasPressureTemperature))
      temperature_ = b.state_position("temperature", name());
    if (std::any_of(used_.begin(), used_.end(), [](const Used& u) {
          return u.shape == discrepancy::Shape::kContactTopOut || u.shape == discrepancy::Shape::kContactTopOutRate;
        }))
      contact_position_ = b.parameter_position(97);
  }
  template <class S>
  void Eval(TermContext<S>& c) const {
    using discrepancy::Shape;
    namespace d = discrepancy;
    const auto& v = *c.v;
    const bool balance = c.phase == TermContext<S>::Phase::kBalance;
    if (!balance && c.phase != TermContext<S>::Phase::kGasState) return;
    const S& rate = v.stroke_rate;
    const S s = v.stroke * (1.0 / d::kStroke);
    for (const Used& u : used_) {
      const S& coefficient = c.theta[u.position];
      switch (u.shape) {
        case Shape::kDampingDirection:
          if (balance) c.force += coefficient * c.theta[damping_] * rate * rate;
          break;
        case Shape::kDampingStroke:
          if (balance) c.force += coefficient * c.theta[damping_] * s * rate * Abs(rate);
          break;
        case Shape::kDampingStrokeDirection:
          if (balance) c.force += coefficient * c.theta[damping_] * s * rate * rate;
          break;
        case Shape::kDampingStrokeSquared:
          if (balance) c.force += coefficient * c.theta[damping_] * s * s * rate * Abs(rate);
          break;
        case Shape::kViscous:
          if (balance) c.force += coefficient * c.theta[damping_] * d::kRate * rate;
          break;
        case Shape::kViscousDirection:
          if (balance)
            c.force += coefficient * c.theta[damping_] * d::kRate * rate * (2.0 / std::numbers::pi) *
                       Atan(S(rate * (1.0 / d::kDirection)));
          break;
        case Shape::kDampingPressure:
          if (balance)
            c.force += coefficient * c.theta[damping_] * d::kRate * rate * v.states[pressure_] * (1.0 / d::kLoopPressure);
          break;
        case Shape::kFrictionDirection:
        case Shape::kFrictionStroke:
          if (balance) {
            const S amplitude = c.theta[friction_base_] + c.theta[friction_pressure_] * v.states[pressure_];
            const S a = Atan(S(c.theta[sharpness_] * rate));
            if (u.shape == Shape::kFrictionDirection)
              c.force += coefficient * amplitude * (2.0 / std::numbers::pi) * a * a;
            else
              c.force += coefficient * amplitude * a * s;
          }
          break;
        case Shape::kStiffnessSquared:
          if (balance) c.force += coefficient * c.theta[area_] * d::kPressure * s * s;
          break;
        case Shape::kStiffnessCubed:
          if (balance) c.force += coefficient * c.theta[area_] * d::kPressure * s * s * s;
          break;
        case Shape::kForceDrift:
          if (balance) c.force += coefficient * c.theta[area_] * d::kPressure * c.theta[time_];
          break;
        case Shape::kVolumeSquared:
          if (!balance) c.gas_volume += coefficient * s * s;
          break;
        case Shape::kVolumeCubed:
          if (!balance) c.gas_volume += coefficient * s * s * s;
          break;
        case Shape::kGasPressure:
          if (!balance) c.gas_amount += coefficient * v.states[pressure_] * (1.0 / d::kLoopPressure);
          break;
        case Shape::kGasDrift:
          if (!balance) c.gas_amount += coefficient * c.theta[time_];
          break;
        case Shape::kForceStatic:
        case Shape::kForceStaticSquared:
          if (balance) {
            const S z = c.theta[static_position_] * (1.0 / d::kStroke);
            c.force += coefficient * c.theta[area_] * d::kPressure * (u.shape == Shape::kForceStatic ? z : z * z);
          }
          break;
        case Shape::kGasStatic:
        case Shape::kGasStaticSquared:
          if (!balance) {
            const S z = c.theta[static_position_] * (1.0 / d::kStroke);
            c.gas_amount += coefficient * (u.shape == Shape::kGasStatic ? z : z * z);
          }
          break;
        case Shape::kVolumePressure:
          if (!balance) c.gas_volume += coefficient * v.states[pressure_] * (1.0 / d::kLoopPressure);
          break;
        case Shape::kConductancePressure:
          if (balance) {
            const S x = v.states[pressure_] * (1.0 / d::kHeatFlowPressure);
            const S wall_heat_flow = c.theta[conductance_] * (1.0 + c.theta[per_stroke_] * v.stroke) *
                                     (v.states[temperature_] + c.theta[minus_ambient_]);
            // (x^n - 1) / n, the Box-Cox transform: 0 at 2 MPa whatever n, its slope in ln p there
            // 1, so that the coefficient is the conductance's growth per e-fold of pressure and the
            // exponent only its curvature (x^n alone trades a large coefficient for a small n
            // along a valley the fit creeps through); ln x at n = 0.
            using std::log;
            const S& n = c.theta[exponent_];
            const S ln_x = log(x);
            const S growth = Abs(Value(n)) < 1e-6 ? S(ln_x * (1.0 + 0.5 * n * ln_x))
                                                  : S((Pow(x, n) - 1.0) / n);
            c.state_residuals[temperature_] += coefficient * wall_heat_flow * growth;
          }
          break;
        case Shape::kFrictionLowSpeed:
        case Shape::kFrictionLowSpeedWide:
        case Shape::kFrictionLowSpeedNarrow:
          if (balance) {
            using std::exp;
            const S amplitude = c.theta[friction_base_] + c.theta[friction_pressure_] * v.states[pressure_];
            const double width = u.shape == Shape::kFrictionLowSpeedNarrow ? d::kLowSpeedNarrow
                                 : u.shape == Shape::kFrictionLowSpeed     ? d::kLowSpeed
                                                                           : d::kLowSpeedWide;
            const S ratio = rate * (1.0 / width);
            c.force += coefficient * amplitude * Atan(S(c.theta[sharpness_] * rate)) * S(exp(S(-ratio * ratio)));
          }
          break;
        case Shape::kContactTopOut:
        case Shape::kContactTopOutRate:
          if (balance) {
            const S penetration =
                d::kContactSmoothing * Softplus(S((c.theta[contact_position_] - v.stroke) * (1.0 / d::kContactSmoothing)));
            const S force = coefficient * c.theta[area_] * d::kPressure * penetration * (1.0 / d::kContactLength);
            c.force -= u.shape == Shape::kContactTopOut ? force : S(force * (-rate * (1.0 / d::kRate)));
          }
          break;
        case Shape::kGasPressureTemperature:
          if (!balance)
            c.gas_amount += coefficient * v.states[pressure_] * (1.0 / d::kLoopPressure) *
                            (v.states[temperature_] * (1.0 / kAmbientK) - 1.0);
          break;
      }
    }
  }
  STRUT_TERM_EVALUATE

 private:
  struct Used {
    discrepancy::Shape shape;
    int position;
  };
  static bool IsStatic(discrepancy::Shape s) {
    using discrepancy::Shape;
    return s == Shape::kForceStatic || s == Shape::kForceStaticSquared || s == Shape::kGasStatic ||
           s == Shape::kGasStaticSquared;
  }
  std::vector<Used> used_;
  bool drift_ = false, static_ = false;
  int damping_ = -1, friction_base_ = -1, friction_pressure_ = -1, sharpness_ = -1, area_ = -1, time_ = -1,
      static_position_ = -1, pressure_ = -1, conductance_ = -1, per_stroke_ = -1, minus_ambient_ = -1,
      temperature_ = -1, exponent_ = -1, contact_position_ = -1;
};

// ---------------------------------------------------------------------------------------------
// Generic forced oscillators (docs/silverbox.md): m y'' + d y' + d3 y'^3 + k y + k2 y^2 + k3 y^3 + u0 = u,
// measured output y + y0. The displacement slot is the output y, the drive slot the input u; both
// in the units of the record ([y], [u]: volts for the Silverbox circuit). Indices from theta50 on.

// The channels of a generic oscillator: output y (the unknown under input u), input u. Typical
// values 0.1 (the static solve starts there and limits its steps by them), Newton scales 1e-9.
const StateSpec kOutputY{"y", "[y]", 2, 0.1, 1e-9, 1e-9};
const StateSpec kInputU{"u", "[u]", 0, 0.1, 1e-9, 1e-9};

//! theta50 y'' + theta51 y' + theta52 y: mass, damping and stiffness of a forced oscillator
//! driven by the input u. The base of the generic models; it names the channels y and u.
class LinearOscillator final : public Term {
 public:
  unsigned phases() const override { return kBalancePhase; }
  std::string_view name() const override { return "linear-oscillator"; }
  void Declare(ModelBuilder& b) override {
    // Tiny typical sizes: the estimator scales these by their (data-derived) starting values, whatever
    // the units of the record.
    // Mass and damping of a passive oscillator are positive; the linear stiffness is negative in a
    // bistable (double-well) Duffing oscillator, so it has no sign.
    b.add_parameter({.index = 50, .name = "mass", .unit = "[u] s^2/[y]", .default_value = 1.0,
                     .description = "oscillator mass (input per output acceleration)", .estimate_by_default = true,
                     .typical = 1e-12, .range = kPositive});
    b.add_parameter({.index = 51, .name = "damping", .unit = "[u] s/[y]", .default_value = 0.1,
                     .description = "linear damping (input per output rate)", .estimate_by_default = true,
                     .typical = 1e-12, .range = kNonNegative});
    b.add_parameter({.index = 52, .name = "stiffness", .unit = "[u]/[y]", .default_value = 1.0,
                     .description = "linear stiffness (input per output)", .estimate_by_default = true,
                     .typical = 1e-12});
    b.declare_channels(kOutputY, kInputU, name());
  }
  void Bind(const ModelBuilder& b) override {
    mass_ = b.parameter_position(50);
    damping_ = b.parameter_position(51);
    stiffness_ = b.parameter_position(52);
  }
  template <class S>
  void Eval(TermContext<S>& c) const {
    if (c.phase != TermContext<S>::Phase::kBalance) return;
    const auto& v = *c.v;
    c.force += c.theta[mass_] * v.stroke_accel + c.theta[damping_] * v.stroke_rate + c.theta[stiffness_] * v.stroke;
  }
  STRUT_TERM_EVALUATE

 private:
  int mass_ = -1, damping_ = -1, stiffness_ = -1;
};

//! theta53 y^2: quadratic (asymmetric) stiffness.
class QuadraticStiffness final : public Term {
 public:
  unsigned phases() const override { return kBalancePhase; }
  std::string_view name() const override { return "quadratic-stiffness"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({.index = 53, .name = "quadratic_stiffness", .unit = "[u]/[y]^2", .default_value = 0.0,
                     .description = "quadratic stiffness: input per output squared", .estimate_by_default = true,
                     .typical = 1e-12, .sizes_term = true});
  }
  void Bind(const ModelBuilder& b) override { k2_ = b.parameter_position(53); }
  template <class S>
  void Eval(TermContext<S>& c) const {
    if (c.phase == TermContext<S>::Phase::kBalance) c.force += c.theta[k2_] * c.v->stroke * c.v->stroke;
  }
  STRUT_TERM_EVALUATE

 private:
  int k2_ = -1;
};

//! theta54 y^3: cubic (hardening when positive) stiffness, the Duffing term.
class CubicStiffness final : public Term {
 public:
  unsigned phases() const override { return kBalancePhase; }
  std::string_view name() const override { return "cubic-stiffness"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({.index = 54, .name = "cubic_stiffness", .unit = "[u]/[y]^3", .default_value = 0.0,
                     .description = "cubic stiffness: input per output cubed", .estimate_by_default = true,
                     .typical = 1e-12, .sizes_term = true});
  }
  void Bind(const ModelBuilder& b) override { k3_ = b.parameter_position(54); }
  template <class S>
  void Eval(TermContext<S>& c) const {
    if (c.phase == TermContext<S>::Phase::kBalance)
      c.force += c.theta[k3_] * c.v->stroke * c.v->stroke * c.v->stroke;
  }
  STRUT_TERM_EVALUATE

 private:
  int k3_ = -1;
};

//! theta58 y'^3: cubic (velocity-cubed) damping, growing with the rate like a saturating
//! electronic element; odd in y', so it adds only odd harmonics like the cubic spring.
class CubicDamping final : public Term {
 public:
  unsigned phases() const override { return kBalancePhase; }
  std::string_view name() const override { return "cubic-damping"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({.index = 58, .name = "cubic_damping", .unit = "[u] s^3/[y]^3", .default_value = 0.0,
                     .description = "cubic damping: input per output rate cubed", .estimate_by_default = true,
                     .typical = 1e-12, .sizes_term = true});
  }
  void Bind(const ModelBuilder& b) override { d3_ = b.parameter_position(58); }
  template <class S>
  void Eval(TermContext<S>& c) const {
    if (c.phase != TermContext<S>::Phase::kBalance) return;
    const S& v = c.v->stroke_rate;
    c.force += c.theta[d3_] * v * v * v;
  }
  STRUT_TERM_EVALUATE

 private:
  int d3_ = -1;
};

//! theta55: input offset, the input reading that moves nothing (measured u = true u + theta55).
class InputOffset final : public Term {
 public:
  unsigned phases() const override { return kBalancePhase; }
  std::string_view name() const override { return "input-offset"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({.index = 55, .name = "input_offset", .unit = "[u]", .default_value = 0.0,
                     .description = "input sensor offset: measured = true + offset", .estimate_by_default = true,
                     .typical = 1e-3, .prior_sd = kStrokeZeroPriorSd});
  }
  void Bind(const ModelBuilder& b) override { offset_ = b.parameter_position(55); }
  template <class S>
  void Eval(TermContext<S>& c) const {
    if (c.phase == TermContext<S>::Phase::kBalance) c.force += c.theta[offset_];
  }
  STRUT_TERM_EVALUATE

 private:
  int offset_ = -1;
};

//! theta56: output offset, measured y = true y + theta56 (like stroke-offset for dampers).
class OutputOffset final : public Term {
 public:
  unsigned phases() const override { return 0; }
  std::string_view name() const override { return "output-offset"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({.index = 56, .name = "output_offset", .unit = "[y]", .default_value = 0.0,
                     .description = "output sensor offset: measured = true + offset", .estimate_by_default = true,
                     .typical = 1e-3, .prior_sd = kStrokeZeroPriorSd});
    b.set_output_offset(56);
  }
  void Bind(const ModelBuilder&) override {}
  template <class S>
  void Eval(TermContext<S>&) const {}
  STRUT_TERM_EVALUATE
};

template <class T>
std::shared_ptr<Term> Make() {
  return std::make_shared<T>();
}

}  // namespace

const std::vector<TermEntry>& Catalogue() {
  static const std::vector<TermEntry> entries = {
      {"inertia", &Make<Inertia>, "", "moving mass and gravity (theta1, theta2)"},
      {"gas-force", &Make<GasForce>, "", "gas force theta4 p"},
      {"quadratic-damping", &Make<QuadraticDamping>, "", "orifice damping theta3 q'|q'|"},
      {"pressure-friction", &Make<PressureFriction>, "", "(theta8 + theta9 p) atan(theta10 q')"},
      {"force-offset", &Make<ForceOffset>, "", "constant force offset theta11"},
      {"stroke-offset", &Make<StrokeOffset>, "", "stroke sensor offset theta12"},
      // No locus: its force is a constant, which the residuals cannot show.
      {"load-cell-zero", &Make<LoadCellZero>, "", "load-cell zero theta39, in the force balance only", "", ""},
      {"gas-volume", &Make<GasVolume>, "", "gas volume 1 + theta6 q"},
      {"polytropic-gas", &Make<PolytropicGas>, "", "polytropic gas law theta5 / (1 + theta6 q)^theta7"},
      {"heat-exchange", &Make<HeatExchange>, "polytropic-gas", "ideal gas with wall heat exchange (2 dof)", "loop-frequency",
       "a pressure-stroke loop whose area depends on the frequency: heat flows through the wall"},
      {"gas-solubility", &Make<GasSolubility>, "", "linear gas solubility theta7 (2 dof)", "group-bias",
       "a pressure bias that depends on the static-position group: less free gas at high pressure"},
      {"viscous-damping", &Make<ViscousDamping>, "", "linear seal damping theta18 q'", "velocity",
       "residual force proportional to the stroke velocity: linear (viscous) damping"},
      {"stribeck-friction", &Make<StribeckFriction>, "", "static friction above kinetic, theta19, theta20", "reversal",
       "force spikes at the velocity reversals: static friction above kinetic"},
      {"end-stop", &Make<EndStop>, "", "top-out contact near full extension, theta21..theta24", "extension",
       "residual only near full extension: contact with the top-out stop"},
      {"oil-compressibility", &Make<OilCompressibility>, "", "oil and cylinder compliance theta25..theta27 (theta26 = 1/K_eff)", "pressure-softening",
       "softening that grows with pressure: oil and cylinder compliance"},
      {"dead-volume", &Make<DeadVolume>, "", "isothermal dead volume of the pressure line theta36 = V_d / V0",
       "deep-softening", "a gas law that softens at deep compression: an isothermal dead volume on the pressure line"},
      {"charge-loss", &Make<ChargeLoss>, "", "gas charge lost over the session theta37, by recording time theta38",
       "session-drift", "a pressure level that falls with recording order: gas charge lost during the session"},
      {"real-gas", &Make<RealGas>, "", "virial nitrogen Z(rho, T), theta28..theta31", "pressure-stiffening",
       "stiffening that grows with pressure: real-gas (virial) nitrogen"},
      {"recoil-damping", &Make<RecoilDamping>, "", "extension orifice damping (1 + theta32) theta3", "rate-asymmetry",
       "a loop asymmetric in the stroke rate: more orifice damping in extension than in compression"},
      {"metering-pin", &Make<MeteringPin>, "", "orifice damping growing with stroke theta3 (1 + theta33 q)",
       "position-damping", "damping at the same stroke rate that grows with the static position: a metering pin"},
      {"friction-asymmetry", &Make<FrictionAsymmetry>, "", "friction (1 + theta34 sgn q') times pressure-friction",
       "friction-direction", "a friction level that differs between compression and extension"},
      {"pressure-heat-transfer", &Make<PressureHeatTransfer>, "",
       "wall heat conductance growing as (p / p_charge)^(2/3), weight theta35", "loop-pressure",
       "a thermal loop that grows with the pressure more than one wall conductance allows: natural convection"},
      // No locus: discovery adds its functions one by one when no catalogue term explains what is left.
      {"discrepancy", &Make<Discrepancy>, "", "empirical discrepancy: a sparse sum of library functions, theta70..theta99",
       "", ""},
      // Generic oscillators (docs/silverbox.md); no locus yet: discovery does not propose them.
      {"linear-oscillator", &Make<LinearOscillator>, "", "forced oscillator theta50 y'' + theta51 y' + theta52 y = u", "", ""},
      {"quadratic-stiffness", &Make<QuadraticStiffness>, "", "quadratic stiffness theta53 y^2", "", ""},
      {"cubic-stiffness", &Make<CubicStiffness>, "", "cubic (Duffing) stiffness theta54 y^3", "", ""},
      {"cubic-damping", &Make<CubicDamping>, "", "cubic damping theta58 y'^3", "", ""},
      {"input-offset", &Make<InputOffset>, "", "input sensor offset theta55", "", ""},
      {"output-offset", &Make<OutputOffset>, "", "output sensor offset theta56", "", ""},
  };
  return entries;
}

const std::vector<DiscrepancyFunction>& DiscrepancyLibrary() {
  static const std::vector<DiscrepancyFunction> library = [] {
    std::vector<DiscrepancyFunction> out;
    for (const discrepancy::Function& f : discrepancy::Library()) out.push_back(f.public_part);
    return out;
  }();
  return library;
}

const std::vector<std::string>& BaseTerms(std::string_view base) {
  static const std::vector<std::string> one = {"inertia",        "gas-force",      "quadratic-damping",
                                               "pressure-friction", "force-offset", "load-cell-zero",
                                               "stroke-offset",  "gas-volume",     "polytropic-gas"};
  static const std::vector<std::string> two = [] {
    auto t = one;
    t.back() = "heat-exchange";
    t.push_back("gas-solubility");
    return t;
  }();
  static const std::vector<std::string> oscillator = {"linear-oscillator"};
  static const std::vector<std::string> none;
  if (base == "1dof") return one;
  if (base == "2dof") return two;
  if (base == "linear-oscillator") return oscillator;
  return none;
}

}  // namespace strut::ident
