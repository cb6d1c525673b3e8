#include "strut/qc/quantities.h"

#include <Eigen/Dense>
#include <cmath>
#include <numbers>

#include "strut/daq/session.h"
#include "strut/ident/charge.h"

namespace strut::qc {
namespace {

struct Definition {
  const char* name;
  const char* unit;
  const char* description;
  std::vector<int> needs;  //!< paper indices the model must have
};

const std::vector<Definition>& Definitions() {
  static const std::vector<Definition> defs = {
      {"charge_pressure", "Pa", "gas pressure (absolute) at full extension and ambient temperature: the charge", {5, 6}},
      {"gas_column", "m", "gas volume at full extension over the piston area, V0/A = -1/theta6: oil overfill shortens it",
       {6}},
      {"friction", "N", "seal friction, Coulomb level at the charge (theta8 + theta9 p0) pi/2", {5, 8, 9}},
      {"orifice_damping", "N s^2/m^2", "orifice (quadratic) damping theta3", {3}},
      {"viscous_damping", "N s/m", "linear damping theta18: seal drag and leakage", {18}},
      {"wall_heat_conductance", "W/K", "heat transfer from gas to wall theta16 (thermal time constant)", {16}},
      {"stroke_offset", "m", "stroke transducer zero theta12", {12}},
      {"load_cell_zero", "N", "load cell's reading at atmospheric pressure: theta11 + theta39 + p_atm theta4",
       {4, 11, 39}},
  };
  return defs;
}

double Param(const ident::ParameterSet& d, const std::vector<double>& theta, int index) {
  return theta[d.position_of_index(index)];
}

double Evaluate(const std::string& name, const ident::Model& model, const std::vector<double>& theta) {
  const ident::ParameterSet& d = model.defaults();
  if (name == "charge_pressure") return ident::ChargePressure(model, theta);
  if (name == "gas_column") return -1.0 / Param(d, theta, 6);
  if (name == "friction")
    return (Param(d, theta, 8) + Param(d, theta, 9) * ident::ChargePressure(model, theta)) * std::numbers::pi / 2;
  if (name == "orifice_damping") return Param(d, theta, 3);
  if (name == "viscous_damping") return Param(d, theta, 18);
  if (name == "wall_heat_conductance") return Param(d, theta, 16);
  if (name == "stroke_offset") return Param(d, theta, 12);
  if (name == "load_cell_zero")
    return Param(d, theta, 11) + Param(d, theta, 39) + daq::kGaugeReferencePa * Param(d, theta, 4);
  throw std::logic_error("unknown QC quantity " + name);
}

bool HasAll(const ident::ParameterSet& d, const std::vector<int>& needs) {
  for (int i : needs)
    if (d.position_of_index(i) < 0) return false;
  return true;
}

}  // namespace

const std::vector<std::string>& QuantityNames() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n;
    for (const auto& d : Definitions()) n.push_back(d.name);
    return n;
  }();
  return names;
}

std::vector<Quantity> ComputeQuantities(const ident::Model& model, const std::vector<double>& theta) {
  std::vector<Quantity> out;
  for (const Definition& def : Definitions()) {
    if (!HasAll(model.defaults(), def.needs)) continue;
    out.push_back({def.name, def.unit, def.description, Evaluate(def.name, model, theta), NAN});
  }
  return out;
}

std::vector<Quantity> ComputeQuantities(const ident::Model& model, const ident::FitSummary& fit) {
  const std::vector<double>& theta = fit.parameters.values();
  std::vector<Quantity> out = ComputeQuantities(model, theta);
  const std::vector<int>& est = fit.estimated_positions;
  const int m = static_cast<int>(est.size());
  // Posterior covariance of the estimated parameters from their sd and correlation.
  Eigen::MatrixXd cov(m, m);
  for (int a = 0; a < m; ++a)
    for (int b = 0; b < m; ++b) {
      const double c = fit.correlation.rows() == m ? fit.correlation(a, b) : (a == b ? 1.0 : 0.0);
      cov(a, b) = c * fit.estimates[est[a]].sd * fit.estimates[est[b]].sd;
    }
  for (Quantity& q : out) {
    // Central differences over a step of a hundredth of each parameter's sd: the quantities are
    // smooth and the posterior is narrow, so the linearisation holds over the interval.
    Eigen::VectorXd g = Eigen::VectorXd::Zero(m);
    bool depends = false;
    for (int a = 0; a < m; ++a) {
      const int i = est[a];
      const double h = std::isfinite(fit.estimates[i].sd) && fit.estimates[i].sd > 0 ? 1e-2 * fit.estimates[i].sd
                                                                  : 1e-6 * std::max(1.0, std::abs(theta[i]));
      std::vector<double> up = theta, down = theta;
      up[i] += h;
      down[i] -= h;
      g(a) = (Evaluate(q.name, model, up) - Evaluate(q.name, model, down)) / (2 * h);
      if (g(a) != 0.0) depends = true;
    }
    q.sd = depends ? std::sqrt(std::max(0.0, g.dot(cov * g))) : NAN;
  }
  return out;
}

}  // namespace strut::qc
