// The physics terms of the damper models (method.md, paper eqs. 21-24) and the catalogue that
// compositions are built from. Adding a term: a class here and one row in Catalogue().
#include "terms.h"

#include <cmath>

namespace strut::ident {
namespace {


// Gas pressure as a model state: an algebraic unknown whose equation is the gas law. Keeping p as
// an unknown lets terms that make the law implicit (solubility, compliance) stay local.
const StateSpec kPressureState{"pressure", "Pa", 0, 7.0e5, 1e-3, 1e-3};
// Gas temperature: first-order state of the heat balance.
const StateSpec kTemperatureState{"temperature", "K", 1, 293.15, 1e-6, 1e-6};

constexpr double kAmbientK = 293.15;

//! theta1 (q'' + theta2): moving mass under gravity.
class Inertia final : public Term {
 public:
  std::string_view name() const override { return "inertia"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({1, "moving_mass", "kg", 40.0, "mass moving with the stroke (piston, axle, fixture)"});
    b.add_parameter({2, "gravity", "m/s^2", 9.81, "gravitational acceleration"});
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
  std::string_view name() const override { return "gas-force"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({4, "gas_area", "m^2", 5.0e-3, "pneumatic piston area", true});
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
  std::string_view name() const override { return "quadratic-damping"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({3, "orifice_damping", "N s^2/m^2", 8.0e3, "quadratic (orifice) damping coefficient"});
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
  std::string_view name() const override { return "pressure-friction"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({8, "friction_base", "N", 190.0, "pressure-independent friction amplitude"});
    b.add_parameter({9, "friction_pressure", "m^2", 4.8e-5, "friction amplitude per unit gas pressure"});
    b.add_parameter({10, "friction_sharpness", "s/m", 2000.0, "arctan sharpness of friction in stroke rate"});
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

//! theta11: constant force offset (atmospheric pressure on the piston, load-cell zero).
class ForceOffset final : public Term {
 public:
  std::string_view name() const override { return "force-offset"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({11, "force_offset", "N", -507.0, "constant force offset (-p_atm A plus load-cell zero)", true});
  }
  void Bind(const ModelBuilder& b) override { offset_ = b.parameter_position(11); }
  template <class S>
  void Eval(TermContext<S>& c) const {
    if (c.phase == TermContext<S>::Phase::kBalance) c.force += c.theta[offset_];
  }
  STRUT_TERM_EVALUATE

 private:
  int offset_ = -1;
};

//! theta12: stroke sensor offset, y = q + theta12. Used by Model for inputs and outputs.
class StrokeOffset final : public Term {
 public:
  std::string_view name() const override { return "stroke-offset"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({12, "stroke_offset", "m", 0.0, "stroke sensor offset: measured = true + offset", true, 1e-3});
  }
  void Bind(const ModelBuilder&) override {}
  template <class S>
  void Eval(TermContext<S>&) const {}
  STRUT_TERM_EVALUATE
};

//! 1 + theta6 q: gas volume relative to full extension (theta6 = -A/V0).
class GasVolume final : public Term {
 public:
  std::string_view name() const override { return "gas-volume"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({6, "volume_per_stroke", "1/m", -1.0 / 0.3, "relative gas-volume change per stroke, -A/V0", true});
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
  std::string_view name() const override { return "polytropic-gas"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({5, "extended_pressure", "Pa", 7.0e5, "absolute gas pressure at full extension"});
    b.add_parameter({7, "polytropic_exponent", "-", 1.2, "polytropic exponent of the gas", true});
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
  std::string_view name() const override { return "heat-exchange"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({5, "pressure_per_temperature", "Pa/K", 7.0e5 * (1.0 + 2.0e-5 * kAmbientK) / kAmbientK,
                     "gas pressure per temperature at full extension (m R / V0)"});
    b.add_parameter({15, "gas_heat_capacity", "J/K", 17.9, "effective heat capacity of the gas"});
    b.add_parameter({16, "wall_heat_conductance", "W/K", 2.24, "heat conductance through the wall at full extension", true});
    b.add_parameter({17, "minus_ambient_temperature", "K", -kAmbientK, "minus the ambient (wall) temperature"});
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
  std::string_view name() const override { return "gas-solubility"; }
  void Declare(ModelBuilder& b) override {
    b.add_parameter({7, "gas_solubility", "1/K", 2.0e-5, "linear gas solubility coefficient"});
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
      {"gas-volume", &Make<GasVolume>, "", "gas volume 1 + theta6 q"},
      {"polytropic-gas", &Make<PolytropicGas>, "", "polytropic gas law theta5 / (1 + theta6 q)^theta7"},
      {"heat-exchange", &Make<HeatExchange>, "polytropic-gas", "ideal gas with wall heat exchange (2 dof)"},
      {"gas-solubility", &Make<GasSolubility>, "", "linear gas solubility theta7 (2 dof)"},
  };
  return entries;
}

const std::vector<std::string>& BaseTerms(std::string_view base) {
  static const std::vector<std::string> one = {"inertia",        "gas-force",   "quadratic-damping",
                                               "pressure-friction", "force-offset", "stroke-offset",
                                               "gas-volume",     "polytropic-gas"};
  static const std::vector<std::string> two = [] {
    auto t = one;
    t.back() = "heat-exchange";
    t.push_back("gas-solubility");
    return t;
  }();
  static const std::vector<std::string> none;
  if (base == "1dof") return one;
  if (base == "2dof") return two;
  return none;
}

}  // namespace strut::ident
