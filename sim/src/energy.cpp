#include "strut/sim/energy.h"

#include <fmt/format.h>
#include <stdexcept>
#include <vector>

namespace strut::sim {
namespace {

struct Trace {
  std::vector<double> time, stroke, rate, force, pressure, temperature, pressure_rate, temperature_rate, measured;
};

EnergyBudget Budget(const ident::Model& model, std::span<const double> theta, const Trace& t) {
  const ident::ParameterSet& d = model.defaults();
  const auto at = [&](int index) {
    const int p = d.position_of_index(index);
    return p >= 0 ? theta[p] : 0.0;
  };
  // The dissipative forces: the model's force sum with inertia, gas force and offset switched off,
  // less the same at rest (which leaves the end stop's elastic force out and its Hunt-Crossley
  // damping, theta21 theta22 d q', in).
  std::vector<double> dissipative(theta.begin(), theta.end());
  for (int index : {1, 4, 11}) {
    const int p = d.position_of_index(index);
    if (p >= 0) dissipative[p] = 0.0;
  }
  const bool by_force = model.causality() == ident::Causality::kForceInput;
  const int m = model.unknown_count();
  std::vector<double> x(m), xd(m), xdd(m, 0.0), r(m);
  const std::size_t k = t.time.size();
  std::vector<double> power_in(k), power_dissipated(k), power_wall(k);
  const double capacity = at(15), conductance = at(16), per_stroke = at(6), minus_ambient = at(17);
  for (std::size_t i = 0; i < k; ++i) {
    x[0] = by_force ? t.stroke[i] : 0.0;
    xd[0] = by_force ? t.rate[i] : 0.0;
    x[1] = t.pressure[i], xd[1] = t.pressure_rate[i];
    x[2] = t.temperature[i], xd[2] = t.temperature_rate[i];
    const double u = by_force ? 0.0 : t.measured[i], ud = by_force ? 0.0 : t.rate[i];
    model.Residual<double>(x, xd, xdd, u, ud, 0.0, dissipative, r);
    const double moving = r[0];
    xd[0] = 0.0;
    model.Residual<double>(x, xd, xdd, u, 0.0, 0.0, dissipative, r);
    power_dissipated[i] = (moving - r[0]) * t.rate[i];
    power_in[i] = t.force[i] * t.rate[i];
    power_wall[i] = conductance * (1.0 + per_stroke * t.stroke[i]) * (t.temperature[i] + minus_ambient);
  }
  EnergyBudget b;
  for (std::size_t i = 1; i < k; ++i) {
    const double h = 0.5 * (t.time[i] - t.time[i - 1]);
    b.work_in += h * (power_in[i] + power_in[i - 1]);
    b.dissipated += h * (power_dissipated[i] + power_dissipated[i - 1]);
    b.heat_to_wall += h * (power_wall[i] + power_wall[i - 1]);
  }
  const double mass = at(1), gravity = at(2);
  const auto stored = [&](std::size_t i) {
    return capacity * t.temperature[i] + mass * (0.5 * t.rate[i] * t.rate[i] + gravity * t.stroke[i]);
  };
  b.stored_change = stored(k - 1) - stored(0);
  return b;
}

void CheckModel(const ident::Model& model, std::span<const double> theta, const TransientResult& result, long first,
                long& last) {
  if (!model.has_term("heat-exchange") || model.unknown_count() != 3)
    throw std::invalid_argument(fmt::format("energy budget: model '{}' has no heat exchange (pressure and temperature "
                                            "states); the budget needs the gas temperature",
                                            model.composition()));
  if (static_cast<int>(theta.size()) != model.parameter_count())
    throw std::invalid_argument("energy budget: wrong number of parameter values");
  const long count = static_cast<long>(result.time.size());
  if (last < 0) last = count - 1;
  if (first < 0 || last >= count || last - first < 1)
    throw std::invalid_argument(fmt::format("energy budget: bad sample range [{}, {}] of {}", first, last, count));
}

}  // namespace

EnergyBudget ComputeEnergyBudget(const ident::Model& model, std::span<const double> theta, const TransientResult& result,
                                 long first, long last) {
  CheckModel(model, theta, result, first, last);
  if (model.causality() != ident::Causality::kForceInput)
    throw std::invalid_argument("energy budget: a stroke-input run needs its input signal (the other overload)");
  Trace t;
  for (long i = first; i <= last; ++i) {
    t.time.push_back(result.time[i]);
    t.stroke.push_back(result.unknowns(0, i));
    t.rate.push_back(result.rates(0, i));
    t.force.push_back(result.input[i]);
    t.pressure.push_back(result.unknowns(1, i));
    t.pressure_rate.push_back(result.rates(1, i));
    t.temperature.push_back(result.unknowns(2, i));
    t.temperature_rate.push_back(result.rates(2, i));
  }
  return Budget(model, theta, t);
}

EnergyBudget ComputeEnergyBudget(const ident::Model& model, std::span<const double> theta, const TransientResult& result,
                                 const InputSignal& input, long first, long last) {
  CheckModel(model, theta, result, first, last);
  if (model.causality() != ident::Causality::kStrokeInput)
    throw std::invalid_argument("energy budget: the input-signal overload is for stroke-input runs");
  const int offset = model.has_term("stroke-offset") ? model.defaults().position_of_index(12) : -1;
  Trace t;
  for (long i = first; i <= last; ++i) {
    const InputSample u = input(result.time[i]);
    t.time.push_back(result.time[i]);
    t.measured.push_back(u.value);
    t.stroke.push_back(u.value - (offset >= 0 ? theta[offset] : 0.0));
    t.rate.push_back(u.rate);
    t.force.push_back(result.unknowns(0, i));
    t.pressure.push_back(result.unknowns(1, i));
    t.pressure_rate.push_back(result.rates(1, i));
    t.temperature.push_back(result.unknowns(2, i));
    t.temperature_rate.push_back(result.rates(2, i));
  }
  return Budget(model, theta, t);
}

}  // namespace strut::sim
