#include "strut/ident/initial_values.h"


#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <numbers>

namespace strut::ident {
namespace {

constexpr double kAmbientK = 293.15;

// Least squares x = argmin |A x - b|; returns the residual rms.
double LeastSquares(const Eigen::MatrixXd& a, const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  x = a.colPivHouseholderQr().solve(b);
  return std::sqrt((a * x - b).squaredNorm() / std::max<Eigen::Index>(1, b.size()));
}

struct Window {
  Eigen::VectorXd stroke, rate, accel, force;
};

// The local friction fit at one reversal: profile over the sharpness (linear in the rest), on a
// log grid and then by golden-section search between the best point's neighbours.
bool FitReversal(const Window& w, FrictionReversal& out) {
  const Eigen::Index m = w.force.size();
  if (m < 6) return false;
  Eigen::MatrixXd a(m, 4);
  a.col(0).setOnes();
  a.col(1) = w.stroke;
  a.col(2) = w.accel;
  Eigen::VectorXd x;
  const auto profile = [&](double log_sharpness) {
    const double sharpness = std::pow(10.0, log_sharpness);
    for (Eigen::Index i = 0; i < m; ++i) a(i, 3) = std::atan(sharpness * w.rate[i]);
    return LeastSquares(a, w.force, x);
  };
  constexpr int kGrid = 80;
  const auto log_at = [](int k) { return 1.0 + 5.0 * k / kGrid; };  // 10 .. 1e6 s/m
  int best_k = 0;
  double best = INFINITY;
  for (int k = 0; k <= kGrid; ++k) {
    const double rms = profile(log_at(k));
    if (rms < best) best = rms, best_k = k;
  }
  double lo = log_at(std::max(0, best_k - 1)), hi = log_at(std::min(kGrid, best_k + 1));
  const double golden = (std::sqrt(5.0) - 1.0) / 2.0;
  for (int iteration = 0; iteration < 30; ++iteration) {
    const double c = hi - golden * (hi - lo), d = lo + golden * (hi - lo);
    if (profile(c) < profile(d)) hi = d; else lo = c;
  }
  const double log_sharpness = 0.5 * (lo + hi);
  out.rms = profile(log_sharpness);
  if (!std::isfinite(out.rms) || !(x[3] > 0)) return false;
  out.amplitude = x[3];
  out.sharpness = std::pow(10.0, log_sharpness);
  return true;
}

}  // namespace

FrictionEstimate PreidentifyFriction(const std::vector<ExperimentData>& data) {
  FrictionEstimate result;
  for (const ExperimentData& e : data) {
    const auto s = e.channels.find("stroke"), f = e.channels.find("force"), p = e.channels.find("pressure");
    if (s == e.channels.end() || f == e.channels.end() || p == e.channels.end()) continue;
    const PeriodicSeries stroke = PeriodicSeries::Fit(s->second.mean, e.frequency);
    const int count = static_cast<int>(e.phases.size());
    const Eigen::VectorXd stroke_fit = stroke.OnPhases(count, 0), rate = stroke.OnPhases(count, 1),
                          accel = stroke.OnPhases(count, 2);
    for (int i = 0; i < count; ++i) {
      const int next = (i + 1) % count;
      if ((rate[i] > 0) == (rate[next] > 0) || rate[i] == 0.0) continue;
      // A reversal between i and next: fit the points within 5 % of a period either side.
      const int half = std::max(3, static_cast<int>(0.05 * count));
      Window w{Eigen::VectorXd(2 * half + 2), Eigen::VectorXd(2 * half + 2), Eigen::VectorXd(2 * half + 2),
               Eigen::VectorXd(2 * half + 2)};
      for (int k = -half; k <= half + 1; ++k) {
        const int j = ((i + k) % count + count) % count;
        const Eigen::Index row = k + half;
        w.stroke[row] = stroke_fit[j];
        w.rate[row] = rate[j];
        w.accel[row] = accel[j];
        w.force[row] = f->second.mean[j];
      }
      FrictionReversal r;
      r.experiment = e.label;
      r.top = rate[i] > 0;
      r.pressure = 0.5 * (p->second.mean[i] + p->second.mean[next]);
      if (FitReversal(w, r)) result.reversals.push_back(r);
    }
  }
  if (result.reversals.size() < 2) {
    result.note = "fewer than two velocity reversals could be fitted";
    return result;
  }
  // Amplitude linear in pressure over all reversals (paper Fig. 7).
  const Eigen::Index m = static_cast<Eigen::Index>(result.reversals.size());
  Eigen::MatrixXd a(m, 2);
  Eigen::VectorXd b(m);
  std::vector<double> sharpness;
  for (Eigen::Index i = 0; i < m; ++i) {
    a(i, 0) = 1.0;
    a(i, 1) = result.reversals[i].pressure;
    b[i] = result.reversals[i].amplitude;
    sharpness.push_back(result.reversals[i].sharpness);
  }
  Eigen::VectorXd x;
  const double spread = a.col(1).maxCoeff() - a.col(1).minCoeff();
  if (spread > 0.1 * a.col(1).mean()) {
    LeastSquares(a, b, x);
  } else {
    x = Eigen::Vector2d(b.mean(), 0.0);
    result.note = "one pressure level only: friction taken as independent of pressure";
  }
  std::nth_element(sharpness.begin(), sharpness.begin() + sharpness.size() / 2, sharpness.end());
  result.base = x[0];
  result.per_pressure = x[1];
  result.sharpness = sharpness[sharpness.size() / 2];
  // A jump sharper than the samples resolve fits any sharpness beyond it equally (the profile runs to
  // its 1e6 s/m end, and a Stribeck spike pushes it there); such a start leaves the fit no gradient.
  // 5e4 s/m switches within 0.02 mm/s, under one sample's change of the rate at a 0.04 Hz reversal.
  constexpr double kSharpestResolved = 5e4;
  if (result.sharpness > kSharpestResolved) {
    result.note += fmt::format("{}sharpness {:.3g} s/m at the reversals is beyond what the samples resolve; "
                               "started at {:.3g}",
                               result.note.empty() ? "" : "; ", result.sharpness, kSharpestResolved);
    result.sharpness = kSharpestResolved;
  }
  result.ok = std::isfinite(result.base) && std::isfinite(result.per_pressure);
  return result;
}

namespace {

//! theta1, theta3, theta4, theta8, theta9, theta11 (and theta18 with viscous damping) by linear
//! least squares on F = theta1 (q'' + g) + theta3 q'|q'| + theta4 p + (theta8 + theta9 p)
//! atan(theta10 q') [+ theta18 q'] + theta11 over all experiments, theta10 as `values` hold it.
//! Applied only when every coefficient comes out physical.
template <class Set>
void ForceBalanceRegression(const Model& model, const std::vector<ExperimentData>& data, const ParameterSet& values,
                            const Set& set) {
  const int sharpness = values.position_of_index(10), gravity = values.position_of_index(2);
  if (sharpness < 0 || gravity < 0 || !model.has_term("quadratic-damping") || !model.has_term("inertia")) return;
  const bool viscous = model.has_term("viscous-damping");
  const int columns = viscous ? 7 : 6;
  std::vector<Eigen::RowVectorXd> rows;
  std::vector<double> force;
  int experiments = 0;
  for (const ExperimentData& e : data) {
    if (!e.channels.count("stroke") || !e.channels.count("force") || !e.channels.count("pressure")) continue;
    const PeriodicSeries stroke = PeriodicSeries::Fit(e.channels.at("stroke").mean, e.frequency);
    const Eigen::VectorXd& f = e.channels.at("force").mean;
    const Eigen::VectorXd& p = e.channels.at("pressure").mean;
    ++experiments;
    const int count = static_cast<int>(e.phases.size());
    const Eigen::VectorXd rates = stroke.OnPhases(count, 1), accels = stroke.OnPhases(count, 2);
    for (int i = 0; i < count; ++i) {
      const double rate = rates[i], accel = accels[i];
      const double friction = std::atan(values.value(sharpness) * rate);
      Eigen::RowVectorXd row(columns);
      row << accel, rate * std::abs(rate), p[static_cast<Eigen::Index>(i)], friction,
          friction * p[static_cast<Eigen::Index>(i)], 1.0;
      if (viscous) row[6] = rate;
      rows.push_back(row);
      force.push_back(f[static_cast<Eigen::Index>(i)]);
    }
  }
  if (experiments < 2 || rows.size() < 50) return;
  Eigen::MatrixXd a(static_cast<Eigen::Index>(rows.size()), columns);
  for (std::size_t i = 0; i < rows.size(); ++i) a.row(static_cast<Eigen::Index>(i)) = rows[i];
  // Columns scaled to unit norm: accelerations, pressures and ones differ by 10 orders.
  const Eigen::VectorXd norms = a.colwise().norm().transpose().cwiseMax(1e-300);
  Eigen::VectorXd x;
  LeastSquares(a * norms.cwiseInverse().asDiagonal(), Eigen::Map<Eigen::VectorXd>(force.data(), force.size()), x);
  x = x.cwiseQuotient(norms);
  if (!(x[0] > 0 && x[1] >= 0 && x[2] > 0 && x.allFinite())) return;
  const std::string how = fmt::format("force balance over {} experiments with the measured pressure", experiments);
  set(1, x[0], how);
  set(3, x[1], how);
  set(4, x[2], how);
  set(8, x[3], how);
  set(9, x[4], how);
  set(11, x[5] - x[0] * values.value(gravity), how + ", less the weight of the moving mass");
  if (viscous && x[6] >= 0) set(18, x[6], how);
}

// The gas law's start for a model with a gas temperature state (heat-exchange): ideal gas near
// ambient temperature from pressure against stroke.
template <class Set>
void IdealGasStart(const Model& model, const std::vector<ExperimentData>& data, const ExperimentData& slow,
                   const std::string& where, const ParameterSet& values, const Set& set) {
  const Eigen::VectorXd& y = slow.channels.at("stroke").mean;
  const Eigen::VectorXd& p = slow.channels.at("pressure").mean;
  const Eigen::Index m = y.size();
  Eigen::VectorXd x;
  // Ideal gas near ambient temperature: 1/p = (1 + theta6 q) / (theta5 T) + theta7 / theta5. Slow
  // large strokes swing the gas temperature by tens of kelvin, so use the cycle means of the
  // small-amplitude experiments (gas close to ambient on average) at their static positions.
  std::vector<std::pair<double, double>> points;  // (mean stroke, mean pressure)
  for (const ExperimentData& e : data)
    if (e.amplitude < 0.04 && e.channels.count("stroke") && e.channels.count("pressure"))
      points.emplace_back(e.channels.at("stroke").mean.mean(), e.channels.at("pressure").mean.mean());
  double stroke_spread = 0.0;
  for (const auto& [q, pressure] : points) stroke_spread = std::max(stroke_spread, std::abs(q - points[0].first));
  Eigen::MatrixXd b;
  Eigen::VectorXd inverse_pressure;
  std::string how;
  if (points.size() >= 2 && stroke_spread > 0.05) {
    b.resize(static_cast<Eigen::Index>(points.size()), 2);
    inverse_pressure.resize(b.rows());
    for (Eigen::Index i = 0; i < b.rows(); ++i) {
      b(i, 0) = 1.0;
      b(i, 1) = points[i].first;
      inverse_pressure[i] = 1.0 / points[i].second;
    }
    how = fmt::format("cycle means of {} small-amplitude experiments, gas at ambient temperature", points.size());
  } else {
    b.resize(m, 2);
    b.col(0).setOnes();
    b.col(1) = y;
    inverse_pressure = p.cwiseInverse();
    how = where + ", isothermal gas at ambient temperature";
  }
  LeastSquares(b, inverse_pressure, x);
  const int solubility = values.position_of_index(7);
  const double theta7 = solubility >= 0 && model.has_term("gas-solubility") ? values.value(solubility) : 0.0;
  const double theta5 = (1.0 + theta7 * kAmbientK) / (x[0] * kAmbientK);
  set(5, theta5, how);
  set(6, x[1] * theta5 * kAmbientK, how);
}

// The gas law's start for a polytropic gas (no temperature state).
template <class Set>
void PolytropicGasStart(const ExperimentData& slow, const std::string& where, const Set& set) {
  const Eigen::VectorXd& y = slow.channels.at("stroke").mean;
  const Eigen::VectorXd& p = slow.channels.at("pressure").mean;
  const Eigen::Index m = y.size();
  const double y_max = y.maxCoeff();
  Eigen::VectorXd x;
  // Polytropic: log p = log theta5 - theta7 log(1 + theta6 q); profile over the gas column length.
  double best = INFINITY, best_column = 0.0;
  Eigen::VectorXd best_x;
  for (int k = 0; k <= 200; ++k) {
    const double column = (y_max + 1e-3) * std::pow(100.0, k / 200.0);  // from just past the stroke to 100x
    Eigen::MatrixXd b(m, 2);
    b.col(0).setOnes();
    for (Eigen::Index i = 0; i < m; ++i) b(i, 1) = -std::log(1.0 - y[i] / column);
    const double rms = LeastSquares(b, p.array().log().matrix(), x);
    if (rms < best) best = rms, best_column = column, best_x = x;
  }
  set(5, std::exp(best_x[0]), where + ", polytropic fit");
  set(6, -1.0 / best_column, where + ", polytropic fit");
  set(7, best_x[1], where + ", polytropic fit");
}

}  // namespace

ParameterSet InitialValuesFromData(const Model& model, const std::vector<ExperimentData>& data,
                                   std::vector<std::string>* log, std::vector<std::string>* sources) {
  if (sources) sources->assign(model.parameter_count(), "physical default");
  // Generic oscillators have their own (equation-error) starting values.
  if (model.has_term("linear-oscillator")) {
    if (sources) sources->assign(model.parameter_count(), "equation-error fit");
    return OscillatorInitialValues(model, data, log);
  }
  ParameterSet values = model.defaults();
  const auto note = [&](const std::string& line) {
    if (log) log->push_back(line);
  };
  // Where each value came from; one log line per parameter at the end (a later rule may refine
  // what an earlier one set).
  std::vector<std::string> source_of(values.size(), "physical default");
  const auto set = [&](int index, double value, const std::string& source) {
    const int position = values.position_of_index(index);
    if (position < 0 || !std::isfinite(value)) return;
    values.values()[position] = value;
    source_of[position] = source;
  };
  // The slowest experiment (largest amplitude among equals) is the closest to static.
  const ExperimentData* slow = nullptr;
  for (const ExperimentData& e : data)
    if (e.channels.count("stroke") && e.channels.count("force") && e.channels.count("pressure") &&
        (!slow || e.frequency < slow->frequency ||
         (e.frequency == slow->frequency && e.amplitude > slow->amplitude)))
      slow = &e;
  if (slow) {
    const Eigen::VectorXd& y = slow->channels.at("stroke").mean;
    const Eigen::VectorXd& force = slow->channels.at("force").mean;
    const Eigen::VectorXd& p = slow->channels.at("pressure").mean;
    const PeriodicSeries stroke = PeriodicSeries::Fit(y, slow->frequency);
    const Eigen::Index m = y.size();
    // Force = theta4 p + constant + friction sign: up and down strokes average the friction out.
    Eigen::MatrixXd a(m, 3);
    const Eigen::VectorXd rate = stroke.OnPhases(static_cast<int>(m), 1);
    for (Eigen::Index i = 0; i < m; ++i) {
      a(i, 0) = p[i];
      a(i, 1) = 1.0;
      a(i, 2) = rate[i] >= 0 ? 1.0 : -1.0;
    }
    Eigen::VectorXd x;
    LeastSquares(a, force, x);
    const std::string where = fmt::format("static relation of experiment '{}'", slow->label);
    set(4, x[0], where);
    const int mass = values.position_of_index(1), gravity = values.position_of_index(2);
    const double weight = mass >= 0 && gravity >= 0 ? values.value(mass) * values.value(gravity) : 0.0;
    set(11, x[1] - weight, where + ", less the weight of the moving mass");
    const double coulomb = x[2];
    // Gas law from pressure against the measured stroke (its offset theta12 starts at 0).
    if (model.has_term("heat-exchange"))
      IdealGasStart(model, data, *slow, where, values, set);
    else
      PolytropicGasStart(*slow, where, set);
    // Friction: the reversals when they can be fitted, else the static relation's Coulomb level.
    const FrictionEstimate friction = PreidentifyFriction(data);
    if (friction.ok) {
      const std::string how = fmt::format("force jumps at {} velocity reversals{}", friction.reversals.size(),
                                          friction.note.empty() ? "" : "; " + friction.note);
      set(8, friction.base, how);
      set(9, friction.per_pressure, how);
      set(10, friction.sharpness, how);
    } else {
      set(8, coulomb * 2.0 / std::numbers::pi, "Coulomb level of the static relation (" + friction.note + ")");
      set(9, 0.0, "no reversal fit: " + friction.note);
    }
    // The force balance over every experiment, with the measured pressure: linear in the mass, the
    // orifice damping, the gas area, the friction amplitudes and the offset once the friction's
    // sharpness is known (stroke rates from each experiment's series). Better than the slow
    // experiment's static relation where the fast experiments show inertia and damping.
    ForceBalanceRegression(model, data, values, set);
  } else {
    note("no experiment with stroke, force and pressure: all starting values are the model defaults");
  }
  for (int i = 0; i < values.size(); ++i)
    note(fmt::format("{} {} = {:.6g} {} ({})", values.spec(i).key(), values.spec(i).name, values.value(i),
                     values.spec(i).unit, source_of[i]));
  if (sources) *sources = source_of;
  return values;
}

}  // namespace strut::ident
