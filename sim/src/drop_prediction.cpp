#include "strut/sim/drop_prediction.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <map>
#include <cmath>
#include <stdexcept>

namespace strut::sim {
namespace {

using Clock = std::chrono::steady_clock;

//! Two-sided normal quantile for probability `level` (bisection on erfc; the level is validated).
double NormalQuantile(double level) {
  double lo = 0.0, hi = 10.0;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (std::erfc(mid / std::sqrt(2.0)) > 1.0 - level ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

//! Index of the largest sample and the peak's time and value refined by a parabola through it and
//! its neighbours (the vertex, kept within the neighbours).
struct Peak {
  std::size_t index = 0;
  double time = NAN, value = NAN;
};
Peak FindPeak(const std::vector<double>& t, const std::vector<double>& y, std::size_t from = 0) {
  Peak p;
  if (from >= y.size()) return p;
  p.index = static_cast<std::size_t>(std::max_element(y.begin() + from, y.end()) - y.begin());
  p.time = t[p.index];
  p.value = y[p.index];
  if (p.index > from && p.index + 1 < y.size()) {
    const double a = y[p.index - 1], b = y[p.index], c = y[p.index + 1];
    const double curvature = a - 2 * b + c;
    if (curvature < 0) {
      const double shift = std::clamp(0.5 * (a - c) / curvature, -1.0, 1.0);
      const double dt = 0.5 * (t[p.index + 1] - t[p.index - 1]);
      p.time += shift * dt;
      p.value = b - 0.25 * (a - c) * shift;
    }
  }
  return p;
}

}  // namespace

const std::vector<DropFigureName>& DropFigureNames() {
  static const std::vector<DropFigureName> names = {
      {"peak_force", "N"},    {"time_of_peak_force", "s"}, {"max_stroke", "m"},
      {"time_of_max_stroke", "s"}, {"rebound", "m"},       {"peak_pressure", "Pa"},
      {"final_stroke", "m"},  {"time_to_final", "s"},      {"static_stroke", "m"}, {"time_to_static", "s"}};
  return names;
}

std::vector<double> FigureValues(const DropFigures& f) {
  return {f.peak_force, f.time_of_peak_force, f.max_stroke,   f.time_of_max_stroke, f.rebound,
          f.peak_pressure, f.final_stroke,   f.time_to_final, f.static_stroke, f.time_to_static};
}

DropFigures MeasureDrop(const DropTrace& trace, double static_stroke, double settle_band) {
  const std::size_t k = trace.time.size();
  if (k < 3) throw std::invalid_argument(fmt::format("drop figures: {} samples, need at least 3", k));
  if (trace.stroke.size() != k || trace.force.size() != k || (!trace.pressure.empty() && trace.pressure.size() != k))
    throw std::invalid_argument("drop figures: time, stroke, force and pressure differ in length");
  DropFigures f;
  const Peak force = FindPeak(trace.time, trace.force);
  f.peak_force = force.value;
  f.time_of_peak_force = force.time;
  const Peak stroke = FindPeak(trace.time, trace.stroke);
  f.max_stroke = stroke.value;
  f.time_of_max_stroke = stroke.time;
  // The least stroke after the deepest one (the mass bouncing back, or the gas cooling pulling it
  // down), refined like a peak of -stroke.
  std::vector<double> negated(k);
  for (std::size_t i = 0; i < k; ++i) negated[i] = -trace.stroke[i];
  const Peak trough = FindPeak(trace.time, negated, stroke.index);
  f.rebound = f.max_stroke + trough.value;
  if (!trace.pressure.empty()) f.peak_pressure = FindPeak(trace.time, trace.pressure).value;
  f.final_stroke = trace.stroke.back();
  f.static_stroke = static_stroke;
  // The first time from which the stroke stays within the band about `target` (NaN: it leaves the
  // band at the last sample).
  const auto settled = [&](double target) {
    const double band = settle_band * std::abs(target);
    for (std::size_t i = k; i-- > 0;)
      if (std::abs(trace.stroke[i] - target) > band) return i + 1 < k ? trace.time[i + 1] : NAN;
    return trace.time.front();
  };
  f.time_to_final = settled(f.final_stroke);
  if (std::isfinite(static_stroke)) f.time_to_static = settled(static_stroke);
  return f;
}

DropTrace DropTraceFromRecord(const daq::Experiment& e, double stroke_offset) {
  if (e.kind != daq::ExperimentKind::kDrop)
    throw daq::SessionError(fmt::format("experiment '{}' is a {} experiment, not a drop", e.label, daq::ToString(e.kind)));
  DropTrace t;
  t.time = e.time;
  t.stroke = e.channel("stroke").samples;
  for (double& q : t.stroke) q -= stroke_offset;
  t.force = e.channel("force").samples;
  if (e.find_channel("pressure")) t.pressure = e.absolute_pressure();
  if (const daq::Channel* c = e.find_channel("temperature")) t.temperature = c->samples;
  if (t.time.size() < 3)
    throw daq::SessionError(fmt::format("drop experiment '{}' has {} samples, need at least 3", e.label, t.time.size()));
  return t;
}

bool DropPredictionOptions::IsValid(std::string* error) const {
  const auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (!(duration > 0) || !(duration <= 3600)) return fail(fmt::format("duration must be 0..3600 s, got {}", duration));
  if (!(output_rate > 0) || !std::isfinite(output_rate) || duration * output_rate > 1e7)
    return fail(fmt::format("output rate {} Hz is not positive or gives more than 1e7 samples", output_rate));
  if (duration * output_rate < 3) return fail("fewer than 3 samples: raise the duration or the rate");
  if (!(rtol >= 1e-14) || !(rtol <= 1e-3)) return fail(fmt::format("rtol must be 1e-14..1e-3, got {}", rtol));
  if (!(settle_band > 0) || !(settle_band < 1)) return fail(fmt::format("settle band must be 0..1, got {}", settle_band));
  if (!(level > 0) || !(level < 1)) return fail(fmt::format("level must be 0..1, got {}", level));
  return true;
}

namespace {

//! The drop run at any parameter values: the force-input model, the load and the output times of
//! one prediction.
class DropRun {
 public:
  DropRun(const ident::Model& force_model, double mass, double impact_velocity, const DropPredictionOptions& options)
      : model_(force_model),
        simulator_(force_model, Transient(options)),
        times_(UniformTimes(options.duration, options.output_rate)),
        gravity_(force_model.defaults().position_of_index(2)),
        carried_(options.moving_mass == DropMovingMass::kDroppedWithTheta1 ? force_model.defaults().position_of_index(1)
                                                                           : -1),
        mass_(mass),
        impact_velocity_(impact_velocity),
        settle_band_(options.settle_band) {}

  //! Trace and figures at parameter values `p`; the trace, load, steps and time into `out` when given.
  DropFigures Run(const std::vector<double>& values, DropPrediction* out) const {
    // theta1 carried: it falls with the dropped mass, its weight and inertia theirs (the model's
    // inertia term, written for the shaker's load cell, is not the drop's: it is zeroed).
    std::vector<double> p = values;
    double moving = mass_;
    if (carried_ >= 0) {
      moving += p[carried_];
      p[carried_] = 0.0;
    }
    const DropLoad load{moving, impact_velocity_, gravity_ >= 0 ? p[gravity_] : 9.81};
    const auto t0 = Clock::now();
    const TransientResult r = simulator_.Simulate(p, load, times_);
    DropTrace trace;
    trace.time = r.time;
    trace.stroke.assign(r.unknowns.row(0).begin(), r.unknowns.row(0).end());
    trace.force.assign(r.input.begin(), r.input.end());
    const auto channels = model_.output_channels();
    if (std::find(channels.begin(), channels.end(), "pressure") != channels.end()) {
      const Eigen::VectorXd v = r.channel("pressure");
      trace.pressure.assign(v.begin(), v.end());
    }
    if (std::find(channels.begin(), channels.end(), "temperature") != channels.end()) {
      const Eigen::VectorXd v = r.channel("temperature");
      trace.temperature.assign(v.begin(), v.end());
    }
    // Where the stroke ends: at rest under M g, the gas back at ambient temperature.
    double static_stroke = NAN;
    try {
      static_stroke = model_.StaticEquilibrium(load.mass * load.gravity, p)[0];
    } catch (const ident::ModelError&) {
      // No equilibrium (the mass bottoms the damper): time_to_static stays undefined.
    }
    DropFigures figures = MeasureDrop(trace, static_stroke, settle_band_);
    if (out) {
      out->load = load;
      out->trace = std::move(trace);
      out->ida_steps = r.steps;
      out->nominal_seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    }
    return figures;
  }

 private:
  static TransientOptions Transient(const DropPredictionOptions& options) {
    TransientOptions transient;
    transient.rtol = options.rtol;
    return transient;
  }

  const ident::Model& model_;
  const TransientSimulator simulator_;
  const std::vector<double> times_;
  const int gravity_;  //!< position of the gravity parameter (-1: none, 9.81 m/s^2)
  const int carried_;  //!< position of theta1 when it falls with the mass (-1: it stays on the ground)
  const double mass_, impact_velocity_, settle_band_;
};

//! The figures' gradients along the estimated parameters the intervals use (central differences
//! over +- one sd), in prediction.gradient with their keys in interval_parameters; the others named
//! in interval_notes. Returns the indices into `estimated` of the parameters used.
std::vector<int> FigureGradients(const DropRun& run, const ident::ParameterSet& specs, const std::vector<double>& theta,
                                 int fixture, const std::vector<int>& estimated, const Eigen::MatrixXd& covariance,
                                 DropPrediction& prediction) {
  const std::vector<double> nominal = FigureValues(prediction.figures);
  const int nf = static_cast<int>(nominal.size());
  std::vector<int> used;  // indices into `estimated`
  std::vector<Eigen::VectorXd> columns;
  for (int a = 0; a < static_cast<int>(estimated.size()); ++a) {
    const int i = estimated[a];
    const std::string key = specs.spec(i).key();
    const double sd = std::sqrt(covariance(a, a));
    if (i == fixture) {
      prediction.interval_notes.push_back(key + ": the fixture mass plays no part in a drop");
      continue;
    }
    if (!std::isfinite(sd) || !(sd > 0)) {
      prediction.interval_notes.push_back(key + ": no posterior sd in the fit, left out of the intervals");
      continue;
    }
    // Central differences over +- one sd: the scale on which the posterior explores the figure.
    // A side outside the parameter's physical range is replaced by the nominal value.
    std::vector<double> plus = theta, minus = theta;
    plus[i] += sd;
    minus[i] -= sd;
    const bool plus_ok = specs.spec(i).range.contains(plus[i]), minus_ok = specs.spec(i).range.contains(minus[i]);
    if (!plus_ok && !minus_ok) {
      prediction.interval_notes.push_back(fmt::format(
          "{}: a run one sd off failed (both sides outside the physical range), left out of the intervals", key));
      continue;
    }
    try {
      const std::vector<double> up = plus_ok ? FigureValues(run.Run(plus, nullptr)) : nominal;
      const std::vector<double> down = minus_ok ? FigureValues(run.Run(minus, nullptr)) : nominal;
      prediction.simulations += plus_ok + minus_ok;
      const double span = (plus_ok ? sd : 0.0) + (minus_ok ? sd : 0.0);
      Eigen::VectorXd g(nf);
      for (int f = 0; f < nf; ++f) g[f] = (up[f] - down[f]) / span;
      used.push_back(a);
      columns.push_back(g);
    } catch (const TransientError& e) {  // the drop is not integrable one sd off
      prediction.interval_notes.push_back(fmt::format("{}: a run one sd off failed ({}), left out of the intervals", key, e.what()));
    }
  }
  const int nu = static_cast<int>(used.size());
  prediction.gradient.resize(nf, nu);
  for (int a = 0; a < nu; ++a) {
    prediction.gradient.col(a) = columns[a];
    prediction.interval_parameters.push_back(specs.spec(estimated[used[a]]).key());
  }
  return used;
}

//! Each figure's sd and interval at `level` from the gradients and the covariance of the `used`
//! parameters (linearised: g' C g).
void FigureIntervals(const std::vector<int>& used, const Eigen::MatrixXd& covariance, double level,
                     DropPrediction& prediction) {
  const std::vector<double> nominal = FigureValues(prediction.figures);
  const int nu = static_cast<int>(used.size());
  Eigen::MatrixXd c(nu, nu);
  for (int a = 0; a < nu; ++a)
    for (int b = 0; b < nu; ++b) c(a, b) = covariance(used[a], used[b]);
  const double z = NormalQuantile(level);
  for (int f = 0; f < static_cast<int>(nominal.size()); ++f) {
    FigureUncertainty u;
    const Eigen::VectorXd g = prediction.gradient.row(f).transpose();
    if (std::isfinite(nominal[f]) && g.allFinite()) {
      u.sd = std::sqrt(std::max(0.0, g.dot(c * g)));
      u.lower = nominal[f] - z * u.sd;
      u.upper = nominal[f] + z * u.sd;
    }
    prediction.uncertainty.push_back(u);
  }
}

}  // namespace

std::string_view ToString(DropMovingMass m) {
  return m == DropMovingMass::kDroppedAlone ? "dropped" : "dropped+theta1";
}

std::optional<DropMovingMass> DropMovingMassFrom(std::string_view text) {
  if (text == "dropped") return DropMovingMass::kDroppedAlone;
  if (text == "dropped+theta1") return DropMovingMass::kDroppedWithTheta1;
  return std::nullopt;
}

DropPrediction PredictDrop(const ident::Model& model, std::span<const double> theta_in, double mass,
                           double impact_velocity, const std::vector<int>& estimated, const Eigen::MatrixXd& covariance,
                           const DropPredictionOptions& options) {
  const auto start = Clock::now();
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument("drop prediction: " + error);
  if (!(mass > 0) || !std::isfinite(mass))
    throw std::invalid_argument(fmt::format("drop prediction: the mass must be positive, got {} kg", mass));
  if (!std::isfinite(impact_velocity) || impact_velocity < 0)
    throw std::invalid_argument(
        fmt::format("drop prediction: the impact velocity must be >= 0, got {} m/s", impact_velocity));
  const ident::Model force_model = model.causality() == ident::Causality::kForceInput
                                       ? model
                                       : ident::Model::Build(model.composition(), ident::Causality::kForceInput);
  const ident::ParameterSet& specs = force_model.defaults();
  if (static_cast<int>(theta_in.size()) != specs.size())
    throw std::invalid_argument(fmt::format("drop prediction: {} parameter values for model '{}' with {}",
                                            theta_in.size(), force_model.composition(), specs.size()));
  const int ne = static_cast<int>(estimated.size());
  if (options.intervals && (covariance.rows() != ne || covariance.cols() != ne))
    throw std::invalid_argument(fmt::format("drop prediction: a {}x{} covariance for {} estimated parameters",
                                            covariance.rows(), covariance.cols(), ne));
  std::vector<double> theta(theta_in.begin(), theta_in.end());
  // theta1 stays on the ground (set to 0: the dropped mass moves alone), or moves with the mass.
  const int fixture = options.moving_mass == DropMovingMass::kDroppedAlone ? specs.position_of_index(1) : -1;
  if (fixture >= 0) theta[fixture] = 0.0;
  // The shaker's load-cell zero is a reading's error, not a force the dropped damper feels.
  if (const int zero = specs.position_of_index(39); zero >= 0) theta[zero] = 0.0;

  const DropRun run(force_model, mass, impact_velocity, options);
  DropPrediction prediction;
  prediction.figures = run.Run(theta, &prediction);
  prediction.simulations = 1;
  if (options.intervals) {
    const std::vector<int> used = FigureGradients(run, specs, theta, fixture, estimated, covariance, prediction);
    FigureIntervals(used, covariance, options.level, prediction);
  }
  prediction.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return prediction;
}

ScaledParameters ScaleParameters(std::span<const double> theta, const std::vector<int>& estimated,
                                 const Eigen::MatrixXd& covariance, const std::map<int, double>& factors) {
  ScaledParameters s{std::vector<double>(theta.begin(), theta.end()), covariance};
  for (const auto& [position, factor] : factors) {
    if (position < 0 || position >= static_cast<int>(s.theta.size()))
      throw std::invalid_argument(fmt::format("what-if: no parameter at position {}", position));
    s.theta[position] *= factor;
    const auto it = std::find(estimated.begin(), estimated.end(), position);
    if (it != estimated.end()) {
      const Eigen::Index a = it - estimated.begin();
      s.covariance.row(a) *= factor;
      s.covariance.col(a) *= factor;
    }
  }
  return s;
}

WhatIfDrop PredictDropWhatIf(const ident::Model& model, std::span<const double> theta, double mass,
                             double impact_velocity, const std::vector<int>& estimated,
                             const Eigen::MatrixXd& covariance, const std::map<int, double>& factors,
                             const DropPredictionOptions& options) {
  const ScaledParameters scaled = ScaleParameters(theta, estimated, covariance, factors);
  WhatIfDrop w{PredictDrop(model, scaled.theta, mass, impact_velocity, estimated, scaled.covariance, options), {}};
  if (!factors.empty()) {
    DropPredictionOptions plain = options;
    plain.intervals = false;
    w.unscaled = PredictDrop(model, theta, mass, impact_velocity, {}, Eigen::MatrixXd(), plain);
  }
  return w;
}

// The messages name --compare and --experiment: `strut predict drop` is where a recorded drop is
// chosen, and the user fixes the choice there.
const daq::Experiment& FindDropExperiment(const daq::Session& session, const std::string& label,
                                          const std::string& path) {
  const daq::Experiment* recorded = nullptr;
  for (const daq::Experiment& e : session.experiments) {
    if (!label.empty() ? e.label == label : e.kind == daq::ExperimentKind::kDrop) {
      if (recorded && label.empty())
        throw std::invalid_argument(fmt::format("--compare {}: several drop experiments ('{}', '{}'); choose one "
                                                "with --experiment",
                                                path, recorded->label, e.label));
      recorded = &e;
    }
  }
  if (!recorded)
    throw std::invalid_argument(label.empty() ? fmt::format("--compare {}: no drop experiment in the session", path)
                                              : fmt::format("--compare {}: no experiment '{}'", path, label));
  if (recorded->kind != daq::ExperimentKind::kDrop)
    throw std::invalid_argument(fmt::format("--compare {}: experiment '{}' is not a drop", path, recorded->label));
  return *recorded;
}

MeasuredDrop MeasureRecordedDrop(const daq::Experiment& drop, const ident::ParameterSet& fitted, double static_stroke,
                                 double settle_band) {
  const int offset = fitted.position_of_index(12);
  MeasuredDrop m;
  m.trace = DropTraceFromRecord(drop, offset >= 0 ? fitted.value(offset) : 0.0);
  m.figures = MeasureDrop(m.trace, static_stroke, settle_band);
  m.figures.static_stroke = NAN;
  return m;
}

namespace {

//! The composition's tokens with "2dof" spelled out (the base the other terms extend).
std::vector<std::string> CompositionTokens(const std::string& composition) {
  std::vector<std::string> tokens;
  std::size_t from = 0;
  while (from <= composition.size()) {
    const std::size_t plus = composition.find('+', from);
    tokens.push_back(composition.substr(from, plus == std::string::npos ? std::string::npos : plus - from));
    if (plus == std::string::npos) break;
    from = plus + 1;
  }
  if (!tokens.empty() && tokens.front() == "2dof") {
    tokens.front() = "1dof";
    tokens.insert(tokens.begin() + 1, {"heat-exchange", "gas-solubility"});
  }
  return tokens;
}

std::vector<double> TruthFigures(const ident::Model& model, const ident::ParameterSet& truth, double mass,
                                 double velocity, DropPredictionOptions options) {
  options.intervals = false;
  std::vector<double> theta = model.defaults().values();
  for (int i = 0; i < model.defaults().size(); ++i) {
    const auto at = truth.find(model.defaults().spec(i).key());
    if (!at) throw std::invalid_argument("the truth has no " + model.defaults().spec(i).key());
    theta[i] = truth.value(*at);
  }
  return FigureValues(PredictDrop(model, theta, mass, velocity, {}, Eigen::MatrixXd(), options).figures);
}

}  // namespace

std::vector<MissingPhysics> AttributeMissingPhysics(const std::string& truth_composition,
                                                    const ident::ParameterSet& truth_parameters,
                                                    const ident::Model& fitted, double mass, double impact_velocity,
                                                    const DropPredictionOptions& options, double threshold) {
  const ident::Model truth = ident::Model::Build(truth_composition, ident::Causality::kForceInput);
  std::vector<MissingPhysics> out;
  std::vector<double> with;
  for (const std::string& term : truth.term_names()) {
    if (fitted.has_term(term)) continue;
    MissingPhysics m;
    m.term = term;
    std::vector<std::string> tokens = CompositionTokens(truth.composition());
    const auto at = std::find(tokens.begin() + 1, tokens.end(), term);
    // Heat exchange turns theta5 from a pressure into a pressure per kelvin: without it the truth's
    // values mean something else. Such terms are named with the figures their physics drives.
    if (at == tokens.end() || term == "heat-exchange") {
      m.affects = term == "heat-exchange" || term == "gas-solubility"
                      ? "not separable from the truth's base; it drives the gas's slow response: final_stroke, "
                        "static_stroke and time_to_static (the gas cooling), and the stiffness at the peak"
                      : "not separable from the truth's base";
      out.push_back(m);
      continue;
    }
    tokens.erase(at);
    std::string composition = tokens.front();
    for (std::size_t k = 1; k < tokens.size(); ++k) composition += "+" + tokens[k];
    try {
      if (with.empty()) with = TruthFigures(truth, truth_parameters, mass, impact_velocity, options);
      const std::vector<double> without =
          TruthFigures(ident::Model::Build(composition, ident::Causality::kForceInput), truth_parameters, mass,
                       impact_velocity, options);
      std::string words;
      for (std::size_t f = 0; f < with.size(); ++f) {
        const double change = (with[f] - without[f]) / std::abs(without[f]);
        m.relative_change.push_back(change);
        if (std::isfinite(change) && std::abs(change) > threshold)
          words += fmt::format("{}{} {:+.1f} %", words.empty() ? "" : ", ", DropFigureNames()[f].name, 100 * change);
      }
      m.affects = words.empty() ? fmt::format("no figure by more than {:.1f} %", 100 * threshold) : words;
    } catch (const TransientError& e) {  // the drop without the term is not integrable
      m.affects = fmt::format("could not be separated ({})", e.what());
    } catch (const std::invalid_argument& e) {  // the composition without it cannot be built or run
      m.affects = fmt::format("could not be separated ({})", e.what());
    }
    out.push_back(m);
  }
  return out;
}

}  // namespace strut::sim
