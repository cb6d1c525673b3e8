#include "strut/sim/drop_fit.h"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <optional>
#include <set>

#include "ida_run.h"
#include "strut/sim/transient_predictor.h"

namespace strut::sim {

using ident::Causality;
using ident::DerivativeVector;
using ident::Jet;
using ident::Model;

bool DropFitOptions::IsValid(std::string* error) const {
  if (!(rtol >= 1e-14 && rtol <= 1e-2)) {
    if (error) *error = fmt::format("rtol must be between 1e-14 and 1e-2, got {}", rtol);
    return false;
  }
  return true;
}

struct DropExperimentPredictor::Ida : detail::SundialsContext {};

DropExperimentPredictor::DropExperimentPredictor(const Model& model, const ident::TransientExperimentData& data,
                                                 DropFitOptions options)
    : force_model_(model.causality() == Causality::kForceInput ? model
                                                                : Model::Build(model.composition(), Causality::kForceInput)),
      stroke_model_(Model::Build(model.composition(), Causality::kStrokeInput)),
      time_(data.time),
      mass_(data.drop_mass),
      impact_velocity_(data.impact_velocity),
      options_(options) {
  std::string error;
  if (!options_.IsValid(&error)) throw std::invalid_argument("drop fit options: " + error);
  if (!(mass_ > 0) || !std::isfinite(mass_) || !std::isfinite(impact_velocity_))
    throw std::invalid_argument(fmt::format("drop experiment '{}': needs a positive mass and a finite impact velocity",
                                            data.label));
  if (time_.size() < 2 || time_.front() < 0)
    throw std::invalid_argument(fmt::format("drop experiment '{}': needs sample times from contact (t >= 0)", data.label));
  ida_ = std::make_unique<Ida>();
}

DropExperimentPredictor::~DropExperimentPredictor() = default;

namespace {

//! The parameters IDAS differentiates: the ones `wanted`, less the fixture mass (0 in a drop).
//! Gravity is refused: the drop's load holds it as a known constant.
std::vector<int> DifferentiatedParameters(const Model& model, std::span<const int> wanted) {
  const int np = model.parameter_count();
  if (std::set<int>(wanted.begin(), wanted.end()).size() != wanted.size())
    throw std::invalid_argument("drop predictor: a parameter is listed twice");
  const ident::ParameterSet& defaults = model.defaults();
  const int fixture = defaults.position_of_index(1), gravity = defaults.position_of_index(2);
  std::vector<int> parameters;
  for (int p : wanted) {
    if (p < 0 || p >= np)
      throw std::invalid_argument(fmt::format("drop predictor: parameter position {} is not one of model '{}'", p,
                                              model.composition()));
    if (p == gravity && gravity >= 0)
      throw ident::TransientPredictionError(
          "drop predictor: gravity theta2 is a known constant here; a drop in the fit needs it fixed");
    if (p != fixture) parameters.push_back(p);
  }
  if (static_cast<int>(parameters.size()) > ident::kMaxDerivatives)
    throw std::invalid_argument("drop predictor: too many parameters for the Jets");
  return parameters;
}

//! The sensitivities of the state at contact. The differential states (T at ambient) depend on
//! theta through the static equilibrium, which has no Jet form: central differences, exact for
//! the temperature (linear in theta17). The stroke (0) and its rate (v0) do not depend on theta;
//! IDACalcIC makes the algebraic ones (pressure) consistent.
Eigen::MatrixXd ContactSensitivities(const Model& model, const Model& stroke_model, const DaeSystem& system,
                                     const std::vector<double>& theta, const std::vector<int>& parameters,
                                     const std::vector<double>& pbar, const DropLoad& drop) {
  const int m = model.unknown_count(), ns = static_cast<int>(parameters.size());
  Eigen::MatrixXd s0 = Eigen::MatrixXd::Zero(system.size(), ns);
  const std::vector<bool> differential = system.differential();
  for (int k = 0; k < ns; ++k) {
    const int i = parameters[k];
    const double h = 1e-6 * pbar[k];
    std::vector<double> up = theta, down = theta;
    up[i] += h;
    down[i] -= h;
    const InitialState a = DropContactState(stroke_model, up, drop), b = DropContactState(stroke_model, down, drop);
    for (int j = 1; j < m; ++j)
      if (differential[j]) s0(j, k) = (a.unknowns[j] - b.unknowns[j]) / (2 * h);
  }
  return s0;
}

//! The outputs at the record's times from `ida` (at its consistent start) and, for the
//! `parameters` it differentiates, their sensitivities in the columns of `wanted`.
void SampleOutputs(detail::IdaRun& ida, const Model& model, const DaeSystem& system, const std::vector<double>& time,
                   const std::vector<double>& theta, const std::vector<int>& parameters, std::span<const int> wanted,
                   ident::TransientPrediction& out) {
  const int m = model.unknown_count(), ns = static_cast<int>(parameters.size());
  const int channels = static_cast<int>(out.channels.size());
  const Eigen::Index samples = static_cast<Eigen::Index>(time.size());
  const double t_end = time.back();
  if (!wanted.empty()) out.sensitivities.assign(channels, Eigen::MatrixXd::Zero(samples, static_cast<Eigen::Index>(wanted.size())));
  // Column of each differentiated parameter among the ones asked for.
  std::vector<int> column(ns);
  for (int k = 0; k < ns; ++k)
    column[k] = static_cast<int>(std::find(wanted.begin(), wanted.end(), parameters[k]) - wanted.begin());
  std::vector<Jet> theta_jet;
  for (double v : theta) theta_jet.push_back(ident::MakeConstant(v, ns));
  for (int k = 0; k < ns; ++k) theta_jet[parameters[k]] = Jet(theta[parameters[k]], DerivativeVector::Unit(ns, k));
  std::vector<double> values(channels);
  std::vector<Jet> xs(m), y(channels);
  for (Eigen::Index i = 0; i < samples; ++i) {
    if (time[i] > 0) ida.AdvanceTo(time[i], t_end);
    const auto state = ida.y();
    const double u = system.Input(time[i], ida.yp()).value;
    if (ns == 0) {
      model.Outputs<double>(state.first(m), u, theta, values);
      for (int c = 0; c < channels; ++c) out.outputs(c, i) = values[c];
      continue;
    }
    // The outputs (stroke, pressure) do not depend on the force: it enters as a constant.
    for (int j = 0; j < m; ++j) {
      DerivativeVector d(ns);
      for (int k = 0; k < ns; ++k) d[k] = ida.s(j, k);
      xs[j] = Jet(state[j], d);
    }
    model.Outputs<Jet>(xs, ident::MakeConstant(u, ns), theta_jet, y);
    for (int c = 0; c < channels; ++c) {
      out.outputs(c, i) = y[c].value();
      const auto& d = y[c].derivatives();
      if (d.size() == ns)
        for (int k = 0; k < ns; ++k) out.sensitivities[c](i, column[k]) = d[k];
    }
  }
}

}  // namespace

ident::TransientPrediction DropExperimentPredictor::Predict(std::span<const double> theta_in,
                                                            std::span<const int> wanted) {
  const Model& model = force_model_;
  const int np = model.parameter_count();
  const int m = model.unknown_count();
  if (static_cast<int>(theta_in.size()) != np)
    throw std::invalid_argument(fmt::format("drop predictor: {} parameter values for model '{}' with {}",
                                            theta_in.size(), model.composition(), np));
  const std::vector<int> parameters = DifferentiatedParameters(model, wanted);
  const int ns = static_cast<int>(parameters.size());
  const ident::ParameterSet& defaults = model.defaults();
  const int fixture = defaults.position_of_index(1), gravity = defaults.position_of_index(2);

  std::vector<double> theta(theta_in.begin(), theta_in.end());
  if (fixture >= 0) theta[fixture] = 0.0;  // the dropped mass moves alone
  const DropLoad drop{mass_, impact_velocity_, gravity >= 0 ? theta[gravity] : 9.81};
  TransientOptions integrator;
  integrator.rtol = options_.rtol;

  ident::TransientPrediction out;
  out.channels = model.output_channels();
  out.outputs.resize(static_cast<int>(out.channels.size()), static_cast<Eigen::Index>(time_.size()));
  try {
    const InitialState contact = DropContactState(stroke_model_, theta, drop);
    const Load load = drop;
    const DaeSystem system(model, theta, load);
    const int size = system.size();
    Eigen::VectorXd y0 = Eigen::VectorXd::Zero(size), yp0 = Eigen::VectorXd::Zero(size);
    for (int j = 0; j < m; ++j) y0[j] = contact.unknowns[j];
    y0[m] = contact.stroke_rate;
    yp0[0] = contact.stroke_rate;

    detail::SensitivitySetup setup;
    std::vector<double> pbar(ns);
    Eigen::MatrixXd s0 = Eigen::MatrixXd::Zero(size, ns);
    if (ns > 0) {
      for (int k = 0; k < ns; ++k) {
        const int i = parameters[k];
        pbar[k] = std::max({std::abs(theta[i]), defaults.spec(i).typical_size(), 1e-300});
      }
      s0 = ContactSensitivities(model, stroke_model_, system, theta, parameters, pbar, drop);
      setup.load = &load;
      setup.theta = theta;
      setup.parameters = parameters;
      setup.start = s0;
      setup.pbar = pbar;
      setup.staggered = true;
      setup.error_control = options_.sensitivity_error_control;
    }
    detail::IdaRun ida(ida_->ctx, system, integrator, std::span<const double>(y0.data(), size),
                       std::span<const double>(yp0.data(), size), ns > 0 ? &setup : nullptr);
    const auto first_positive = std::find_if(time_.begin(), time_.end(), [](double t) { return t > 0; });
    ida.ConsistentStart(*first_positive);
    SampleOutputs(ida, model, system, time_, theta, parameters, wanted, out);
    steps_ = ida.steps();
  } catch (const TransientError& e) {  // the integration failed: no prediction at these values
    throw ident::TransientPredictionError(fmt::format("drop predictor: {}", e.what()));
  }
  return out;
}

ident::TransientPredictorFactory DropPredictorFactory(DropFitOptions options) {
  return [options](const Model& model, const ident::TransientExperimentData& data) {
    return std::make_unique<DropExperimentPredictor>(model, data, options);
  };
}

}  // namespace strut::sim
