#include "strut/ident/fit_problem.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <exception>
#include <fmt/format.h>
#include <mutex>
#include <numbers>
#include <spdlog/spdlog.h>
#include <thread>
#include <unsupported/Eigen/FFT>

#include "strut/ident/parallel.h"
#include "strut/ident/estimator.h"

namespace strut::ident {
namespace {

std::vector<std::string> DefaultChannels(const Model& model) {
  // The mechanical output (stroke under force input, force under stroke input; y for a generic
  // oscillator) and the gas pressure when the model has one.
  std::vector<std::string> channels = {model.mechanical_channel()};
  const auto& states = model.states();
  if (std::any_of(states.begin(), states.end(), [](const StateSpec& s) { return s.name == "pressure"; }))
    channels.push_back("pressure");
  return channels;
}

//! The covariance that the noise of a measured input puts on a gradient: for g = dF/du on the
//! n-point input grid (one column per function F), sum over the input's noisy Fourier coefficients
//! c of var(c) (dF/dc)(dF/dc)^T, where dF/dc is g projected on that coefficient's grid function
//! (the mean: 1; harmonic h: cos and sin of 2 pi h tau_mu). The projections are one FFT per column
//! on an equidistant grid, direct sums on any other.
//! Harmonics up to `estimated` (-1: none) are left out: the fit estimates them (errors in variables)
//! and their noise is in the posterior through their elimination.
Eigen::MatrixXd InputNoiseCovariance(const ExperimentData& d, const Eigen::MatrixXd& gradient, int estimated) {
  const Eigen::Index k = gradient.cols();
  const int n = static_cast<int>(gradient.rows());
  Eigen::MatrixXd covariance = Eigen::MatrixXd::Zero(k, k);
  if (!(d.input_harmonic_variance > 0) || d.input_harmonics.empty() || k == 0) return covariance;
  Eigen::MatrixXcd spectra = Eigen::MatrixXcd::Zero(n, k);  // sum_mu g(mu) exp(-i 2 pi h tau_mu)
  if (d.input.phases.empty()) {
    Eigen::FFT<double> fft;
    for (Eigen::Index b = 0; b < k; ++b) {
      Eigen::VectorXcd column(n);
      fft.fwd(column, Eigen::VectorXd(gradient.col(b)));
      spectra.col(b) = column;
    }
  } else {
    // exp(-i 2 pi h tau) for the harmonics in rising order, by powers of the first harmonic's wave.
    Eigen::RowVectorXcd first(n), wave = Eigen::RowVectorXcd::Ones(n);
    for (int mu = 0; mu < n; ++mu) first[mu] = std::polar(1.0, -2.0 * std::numbers::pi * d.input.phases[mu]);
    int power = 0;
    for (const int h : d.input_harmonics) {
      if (h >= n) continue;
      if (h < power) {  // not in rising order: from the mean again
        wave.setOnes();
        power = 0;
      }
      for (; power < h; ++power) wave = wave.cwiseProduct(first);
      spectra.row(h) = wave * gradient;
    }
  }
  for (const int h : d.input_harmonics) {
    if (h >= n || h <= estimated) continue;
    if (h == 0) {
      const Eigen::VectorXd q = spectra.row(0).real().transpose();
      covariance.noalias() += d.input_mean_variance * q * q.transpose();
      continue;
    }
    // cos: Re of the spectrum; sin: -Im (the sign drops out of q q^T).
    const Eigen::VectorXd qc = spectra.row(h).real().transpose(), qs = spectra.row(h).imag().transpose();
    covariance.noalias() += d.input_harmonic_variance * (qc * qc.transpose() + qs * qs.transpose());
  }
  return covariance;
}

//! The composition of a force-driven damper model under stroke input, for MeasuredStrokeStart;
//! empty for other models.
std::optional<Model> StrokeDrivenTwin(const Model& model) {
  if (model.causality() != Causality::kForceInput || model.mechanical_channel() != "stroke") return std::nullopt;
  try {
    Model twin = Model::Build(model.composition(), Causality::kStrokeInput);
    if (twin.unknown_count() == model.unknown_count()) return twin;
  } catch (const ModelError&) {
  }
  return std::nullopt;
}

constexpr double kMeasuredStartMismatch = 0.1;  // rms over the force's range, periodic solution
constexpr double kStaticStartMismatch = 1.0;    // largest over the force's range, static solutions

//! A first guess for a force-driven experiment from what was measured: the recorded stroke (less
//! its sensor offset) and the states of the stroke-driven model on it. From the quasi-static guess a
//! cold solve must find the response to the measured force's noise and friction jumps itself (3-11
//! factorisations on the standard matrix); from here it needs 3-8. Empty when the model is not a
//! force-driven damper, the stroke was not recorded, the stroke-driven solve fails, or the model on
//! the measured stroke misses the measured force (parameters far from the record's).
//! `stroke_driven`: the same composition under stroke input (StrokeDrivenTwin).
std::optional<PeriodicSolution> MeasuredStrokeStart(const Model& model, const Model& stroke_driven,
                                                    const ExperimentData& d, const PeriodicInput& input,
                                                    std::span<const double> theta, int n,
                                                    const PeriodicSolverOptions& options) {
  const auto stroke = d.channels.find("stroke");
  if (stroke == d.channels.end() || stroke->second.mean.size() < 8 || !input.phases.empty()) return std::nullopt;
  try {
    const PeriodicSeries series = PeriodicSeries::Fit(stroke->second.mean, d.frequency);
    const PeriodicInput measured = series.OnGrid(n);
    const Eigen::Map<const Eigen::VectorXd> force(input.values.data(), n);
    const double range = force.maxCoeff() - force.minCoeff();
    // A cheap first test (8 static solves): far from the parameters that explain the record the
    // stroke-driven solve below can take as long as a failed cold solve. On the standard matrix the
    // static force misses the measured one by 0.14-0.48 of its range at the truth, 0.56-348 from
    // 20 % off (experiments a and b: 5-12).
    std::vector<double> at_rest;
    for (int mu = 0; mu < n; mu += std::max(1, n / 8)) {
      at_rest = stroke_driven.StaticEquilibrium(measured.values[mu], theta, at_rest);
      if (!(std::abs(at_rest[0] - force[mu]) <= kStaticStartMismatch * range)) return std::nullopt;
    }
    // The states only start Newton: the stroke-driven solution on the coarse grid (a third of
    // the cost of this start), interpolated.
    const int coarse = options.coarse_points >= 8 && n >= 2 * options.coarse_points && n % options.coarse_points == 0
                           ? options.coarse_points
                           : n;
    PeriodicSolverOptions coarse_options = options;
    coarse_options.coarse_points = 0;
    PeriodicSolver solver(stroke_driven, coarse_options);
    const PeriodicSolution states = solver.Solve(series.OnGrid(coarse), theta);
    // Only near the parameters that explain the record: the model driven by the measured stroke
    // must predict the measured force within a tenth of its range (rms). On the standard matrix
    // that is 0.0002-0.04 at the truth and 0.45-86 from 20 % off, where this start is worse than
    // the quasi-static guess and the force-driven Newton can fail from it.
    const Eigen::VectorXd predicted = states.channel("force");
    const int stride = n / coarse;
    double mismatch = 0.0;
    for (int k = 0; k < coarse; ++k) mismatch += std::pow(predicted[k] - force[k * stride], 2);
    if (!(std::sqrt(mismatch / coarse) <= kMeasuredStartMismatch * range)) return std::nullopt;
    // The stroke unknown is the true stroke: the measured one less the output a zero stroke has
    // (the sensor offset, when the model has one).
    const int m = model.unknown_count();
    std::vector<double> zero(m, 0.0), outputs(model.output_channels().size());
    model.Outputs<double>(zero, 0.0, theta, outputs);
    PeriodicSolution guess;
    guess.scheme = options.scheme;
    guess.frequency = d.frequency;
    guess.n = n;
    guess.unknowns = PeriodicResample(states.unknowns, n);
    for (int mu = 0; mu < n; ++mu) guess.unknowns(0, mu) = measured.values[mu] - outputs[0];
    return guess;
  } catch (const PeriodicSolverError& e) {  // no stroke-driven solution there: the usual cold start
    spdlog::debug("experiment '{}': no start from the measured stroke ({})", d.label, e.what());
    return std::nullopt;
  } catch (const ModelError& e) {  // no static equilibrium at a measured stroke
    spdlog::debug("experiment '{}': no start from the measured stroke ({})", d.label, e.what());
    return std::nullopt;
  }
}

//! The highest harmonic of an experiment's input the fit estimates (errors in variables; -1: none).
int EstimatedInputHarmonics(const Model& model, const EstimatorOptions& options, const ExperimentData& d) {
  const bool on = options.estimate_input.value_or(model.causality() == Causality::kStrokeInput);
  if (!on || d.input_measured.empty() || !(d.input_harmonic_variance > 0) || !(d.input_mean_variance > 0)) return -1;
  return std::min({options.input_harmonics, static_cast<int>(d.input_measured.size()) - 1,
                   (static_cast<int>(d.input.values.size()) - 1) / 2});
}

//! Mean, sd and rms of a channel's residual into its statistics.
void SetResidualStatistics(const Eigen::VectorXd& r, ChannelStatistics& st) {
  st.mean = r.mean();
  st.sd = std::sqrt((r.array() - st.mean).square().sum() / std::max<Eigen::Index>(1, r.size() - 1));
  st.rms = std::sqrt(r.squaredNorm() / r.size());
}

PeriodicSolverOptions SolverOptions(const EstimatorOptions& options, const Model& model) {
  PeriodicSolverOptions o;
  o.scheme = options.scheme.value_or(DefaultScheme(model.causality()));
  o.start_up_periods = options.start_up_periods;
  o.coarse_points = options.coarse_points;
  return o;
}

}  // namespace

// Everything one iterate of the fit needs per experiment.
struct FitProblem::Experiment {
  const ExperimentData* data = nullptr;
  std::unique_ptr<PeriodicPredictor> solver;
  PeriodicSolution solution;
  bool active = true;
  std::vector<bool> channel_fitted;  // per fitted channel: false when the channel has a data defect
  std::string error;
  bool dropped_at_start = false;  // no solution at the starting values; retried as the fit moves
  PeriodicInput input;            // what drives the solver: the data's input, or its estimate
  //! Errors in variables: the input's Fourier coefficients c (the mean; cosine and sine of harmonics
  //! 1 .. `harmonics`) estimated with the parameters, as xi = (c - measured) / sd with the prior
  //! N(0, I). The input on the grid is base + directions xi.
  struct InputEstimate {
    int harmonics = 0;
    Eigen::MatrixXd directions;  // n x (2 harmonics + 1): the coefficients' grid functions times their sd
    Eigen::VectorXd base;        // the input at the measured coefficients (kept harmonics above: the series')
    Eigen::VectorXd xi;
    //! Per fitted channel, d(prediction at the phases)/d xi in the products' rows (SampleColumns),
    //! reused as the parameters' are.
    std::vector<Eigen::MatrixXd> sensitivity_rows;
    //! Per fitted channel, unweighted products of the sensitivities above: J_c^T J_c (lower triangle)
    //! and J^T J_c with the parameters' of the same call; kept while both are reused.
    std::vector<Eigen::MatrixXd> gram, coupling;
    //! Per fitted channel, the residual degrees of freedom the estimate takes (of the last Linearise).
    std::vector<double> dof;
  };
  std::optional<InputEstimate> estimate;
  void UpdateInput() {
    Eigen::Map<Eigen::VectorXd>(input.values.data(), static_cast<Eigen::Index>(input.values.size())) =
        estimate->base + estimate->directions * estimate->xi;
  }
  //! Per fitted channel, d(prediction at the phases)/d(scaled parameters) of the last call that
  //! computed them, in the products' rows (SampleColumns): reused while the fit's steps are below a
  //! percent of the parameters.
  std::vector<Eigen::MatrixXd> sensitivity_rows;
  // Cubic (4-point Lagrange) interpolation from the grid to the data phases (exact where a data
  // phase is a grid point). Linear interpolation would bias the fit by h^2 y''/8, comparable to
  // the parameter uncertainty at n = 800.
  PhaseInterpolation map;
  // A grid much smaller than the phases (a thinned slow experiment) forms the fit's products at the
  // grid's size: its rows stand for the phases' (PhaseProducts). Null: products over the phases.
  std::shared_ptr<const PhaseProducts> products;

  void MapPhases() {
    map = PhaseInterpolation::Cubic(data->input.phases, n(), data->phases);
    if (4 * static_cast<std::size_t>(n()) < 3 * map.taps.size()) products = std::make_shared<PhaseProducts>(map, n());
  }
  //! The number of data phases (the residuals per channel).
  std::size_t phase_count() const { return map.taps.size(); }
  //! Grid functions (n rows) as the rows the products use: at the phases, or PhaseProducts' rows.
  Eigen::MatrixXd SampleColumns(const Eigen::MatrixXd& grid) const {
    return products ? products->Columns(grid) : map.Columns(grid);
  }
  //! Values at the phases (a residual) as the rows the products use.
  Eigen::VectorXd SampleVector(const Eigen::VectorXd& at_phases) const {
    return products ? products->Vector(at_phases) : at_phases;
  }
  //! P^T of a column of SampleColumns' rows mapped back to the phases: the weights on the grid.
  Eigen::VectorXd GridWeights(const Eigen::VectorXd& column, int n) const {
    return products ? products->GridWeights(column) : ToGrid(column, n);
  }
  //! A grid function (n values, any stride) at the data phases.
  template <class Grid>
  Eigen::VectorXd AtPhases(const Grid& grid) const {
    Eigen::VectorXd out(map.taps.size());
    for (std::size_t i = 0; i < map.taps.size(); ++i) {
      double v = 0.0;
      for (int k = 0; k < 4; ++k) v += map.weights[i][k] * grid(map.taps[i][k]);
      out[i] = v;
    }
    return out;
  }
  //! The transpose of AtPhases: values at the data phases spread back onto the n grid points.
  Eigen::VectorXd ToGrid(const Eigen::VectorXd& at_phases, int n) const {
    Eigen::VectorXd grid = Eigen::VectorXd::Zero(n);
    for (std::size_t i = 0; i < map.taps.size(); ++i)
      for (int k = 0; k < 4; ++k) grid[map.taps[i][k]] += map.weights[i][k] * at_phases[static_cast<int>(i)];
    return grid;
  }
  double InputDof(int b) const {
    return estimate && b < static_cast<int>(estimate->dof.size()) ? estimate->dof[b] : 0.0;
  }
  Eigen::VectorXd Residual(const std::string& channel, int row) const {
    return data->channels.at(channel).mean - AtPhases(solution.outputs.row(row));
  }
  //! Grid points of this experiment's periodic solution (at least EstimatorOptions::n; a slow
  //! experiment's grid holds a point per recorded sample: PrepareExperiments).
  int n() const { return static_cast<int>(data->input.values.size()); }
};

// A transient (drop) experiment of the fit: its record, its predictor and the prediction at the
// current parameters.
struct FitProblem::TransientExperiment {
  const TransientExperimentData* data = nullptr;
  std::unique_ptr<TransientExperimentPredictor> predictor;
  std::vector<std::string> recorded;  // per fit channel: the recorded channel fitted there ("": none)
  TransientPrediction prediction;     // outputs at the current parameters (no sensitivities)
  std::vector<Eigen::MatrixXd> sensitivities;  // per fit channel: samples x estimated, scaled (empty: none yet)
  bool active = true;
  bool dropped_at_start = false;
  std::string error;
  bool fitted(int b) const { return !recorded[b].empty(); }
  Eigen::VectorXd Predicted(int b) const {
    const std::string& name = recorded[b];
    for (std::size_t row = 0; row < prediction.channels.size(); ++row)
      if (prediction.channels[row] == name) return prediction.outputs.row(static_cast<Eigen::Index>(row)).transpose();
    throw std::logic_error(fmt::format("drop experiment '{}': the prediction has no '{}' output", data->label, name));
  }
  Eigen::VectorXd Residual(int b) const { return data->channels.at(recorded[b]).samples - Predicted(b); }
};

double ResidualSums::LogLikelihood() const {
  double value = 0.0;
  for (std::size_t b = 0; b < counts.size(); ++b)
    if (counts[b] > 0)
      value -= 0.5 * counts[b] * (std::log(2 * std::numbers::pi * std::max(sum_squares[b] / counts[b], 1e-300)) + 1.0);
  return value;
}

std::vector<double> ResidualSums::Variances(int estimated) const {
  std::vector<double> v(counts.size());
  for (std::size_t b = 0; b < counts.size(); ++b)
    v[b] = std::max(sum_squares[b] / std::max(1.0, counts[b] - estimated - (b < input_dof.size() ? input_dof[b] : 0.0)),
                    1e-300);
  return v;
}

FitProblem::FitProblem(const Model& model, const EstimatorOptions& options, const std::vector<ExperimentData>& data,
                       const std::vector<DataIssue>& issues, std::vector<int> estimated, std::vector<double> scale,
                       const std::vector<TransientExperimentData>& transients)
    : model_(model),
      options_(options),
      estimated_(std::move(estimated)),
      scale_(std::move(scale)),
      stroke_driven_(StrokeDrivenTwin(model)) {
  channels_ = options.channels.empty() ? DefaultChannels(model) : options.channels;
  const std::vector<std::string> outputs = model.output_channels();
  for (const auto& c : channels_) {
    const auto it = std::find(outputs.begin(), outputs.end(), c);
    if (it == outputs.end())
      throw std::invalid_argument(fmt::format("estimator: model {} has no output '{}'", model.composition(), c));
    output_row_.push_back(static_cast<int>(it - outputs.begin()));
  }
  threads_ = options.threads > 0 ? options.threads : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  const int nc = static_cast<int>(channels_.size());
  const PeriodicSolverOptions solver_options = SolverOptions(options, model);
  experiments_.reserve(data.size());
  for (const ExperimentData& d : data) {
    Experiment s;
    s.data = &d;
    s.solver = options.predictor ? options.predictor(model) : std::make_unique<PeriodicSolver>(model, solver_options);
    s.channel_fitted.assign(nc, true);
    if (static_cast<int>(d.input.values.size()) < 8)
      throw std::invalid_argument(fmt::format("estimator: experiment '{}' has {} grid points; at least 8 are needed",
                                              d.label, d.input.values.size()));
    s.MapPhases();
    s.input = d.input;
    if (const int harmonics = EstimatedInputHarmonics(model, options, d); harmonics >= 0) {
      // Start at the thresholded series (the input the fit used before it estimated the input); the
      // prior ties every coefficient to its measured value by the coefficient's noise.
      const int n = s.n(), count = 2 * harmonics + 1;
      Experiment::InputEstimate e;
      e.harmonics = harmonics;
      e.directions.resize(n, count);
      Eigen::VectorXd measured(count), start(count), sd(count);
      const auto kept = [&](int h) {
        return std::find(d.input_harmonics.begin(), d.input_harmonics.end(), h) != d.input_harmonics.end();
      };
      e.directions.col(0).setConstant(1.0);
      measured[0] = d.input_measured[0].real();
      sd[0] = std::sqrt(d.input_mean_variance);
      for (int h = 1; h <= harmonics; ++h) {
        for (int mu = 0; mu < n; ++mu) {
          const double phase = 2.0 * std::numbers::pi * h * d.input.phase(mu);
          e.directions(mu, 2 * h - 1) = std::cos(phase);
          e.directions(mu, 2 * h) = std::sin(phase);
        }
        // u = c_0 + sum 2 Re(c_h exp(i phase)) = c_0 + sum a_h cos + b_h sin
        measured[2 * h - 1] = 2.0 * d.input_measured[h].real();
        measured[2 * h] = -2.0 * d.input_measured[h].imag();
        sd[2 * h - 1] = sd[2 * h] = std::sqrt(d.input_harmonic_variance);
      }
      for (int k = 0; k < count; ++k) {
        const int h = (k + 1) / 2;
        start[k] = h == 0 || kept(h) ? measured[k] : 0.0;
      }
      const Eigen::Map<const Eigen::VectorXd> series(d.input.values.data(), n);
      e.base = series + e.directions * (measured - start);
      e.xi = (start - measured).cwiseQuotient(sd);
      e.directions = e.directions * sd.asDiagonal();
      s.estimate = std::move(e);
    }
    for (int b = 0; b < nc; ++b) {
      if (!d.channels.count(channels_[b])) {
        s.channel_fitted[b] = false;
        warnings_.push_back(fmt::format("{}: experiment '{}' has no '{}' channel; left out of that channel", d.session,
                                        d.label, channels_[b]));
      }
      for (const DataIssue& issue : issues)
        if (issue.experiment == d.label && issue.channel == channels_[b] && s.channel_fitted[b]) {
          s.channel_fitted[b] = false;
          warnings_.push_back(fmt::format("experiment '{}', channel '{}': {} ({}); not fitted", d.label, channels_[b],
                                          issue.kind, issue.detail));
        }
    }
    experiments_.push_back(std::move(s));
  }
  periodic_channels_ = nc;
  // Drops: their channels ("drop:stroke", ...) after the periodic ones, each with its own variance.
  for (const TransientExperimentData& d : transients) {
    if (!options.transient_predictor) {
      warnings_.push_back(fmt::format("{}: {} experiment '{}' left out: this fit has no transient predictor (strut "
                                      "identify has one)",
                                      d.session, d.kind, d.label));
      continue;
    }
    TransientExperiment t;
    t.data = &d;
    try {
      t.predictor = options.transient_predictor(model, d);
    } catch (const TransientPredictionError& e) {  // the predictor cannot take this record
      warnings_.push_back(fmt::format("{}: {} experiment '{}' left out: {}", d.session, d.kind, d.label, e.what()));
      continue;
    } catch (const std::invalid_argument& e) {  // the record's mass, velocity or times are unusable
      warnings_.push_back(fmt::format("{}: {} experiment '{}' left out: {}", d.session, d.kind, d.label, e.what()));
      continue;
    }
    for (const auto& [channel, recorded] : d.channels) {
      const bool defect = std::any_of(issues.begin(), issues.end(), [&](const DataIssue& issue) {
        return issue.experiment == d.label && issue.channel == channel;
      });
      if (defect) continue;
      const std::string name = TransientChannelName(d.kind, channel);
      if (std::find(channels_.begin(), channels_.end(), name) == channels_.end()) channels_.push_back(name);
    }
    transients_.push_back(std::move(t));
  }
  for (TransientExperiment& t : transients_) {
    t.recorded.assign(channels_.size(), "");
    for (const auto& [channel, recorded] : t.data->channels) {
      const auto it = std::find(channels_.begin(), channels_.end(), TransientChannelName(t.data->kind, channel));
      const bool defect = std::any_of(issues.begin(), issues.end(), [&](const DataIssue& issue) {
        return issue.experiment == t.data->label && issue.channel == channel;
      });
      if (it != channels_.end() && !defect) t.recorded[it - channels_.begin()] = channel;
    }
  }
  for (const DataIssue& issue : issues)
    if (std::find(channels_.begin(), channels_.end(), issue.channel) == channels_.end() &&
        std::none_of(transients.begin(), transients.end(),
                     [&](const TransientExperimentData& d) { return d.label == issue.experiment; }))
      warnings_.push_back(
          fmt::format("experiment '{}', channel '{}': {} ({})", issue.experiment, issue.channel, issue.kind, issue.detail));
}

FitProblem::~FitProblem() = default;

int FitProblem::experiment_count() const { return static_cast<int>(experiments_.size()); }

int FitProblem::transient_count() const { return static_cast<int>(transients_.size()); }

int FitProblem::active_count() const {
  return static_cast<int>(std::count_if(experiments_.begin(), experiments_.end(), [](const Experiment& e) { return e.active; }) +
                          std::count_if(transients_.begin(), transients_.end(),
                                        [](const TransientExperiment& t) { return t.active; }));
}

std::vector<std::pair<std::string, std::string>> FitProblem::experiment_labels() const {
  std::vector<std::pair<std::string, std::string>> labels;
  for (const Experiment& s : experiments_) labels.emplace_back(s.data->label, "periodic");
  for (const TransientExperiment& t : transients_) labels.emplace_back(t.data->label, t.data->kind);
  return labels;
}

bool FitProblem::PredictTransient(TransientExperiment& t, const std::vector<double>& theta, bool sensitivities) const {
  const int l = static_cast<int>(estimated_.size());
  try {
    TransientPrediction p = t.predictor->Predict(theta, sensitivities ? std::span<const int>(estimated_)
                                                                      : std::span<const int>());
    const Eigen::Index samples = static_cast<Eigen::Index>(t.data->time.size());
    if (p.outputs.cols() != samples || p.outputs.rows() != static_cast<Eigen::Index>(p.channels.size()) ||
        (sensitivities && p.sensitivities.size() != p.channels.size()))
      throw std::logic_error("the predictor's outputs do not match the record");
    if (!p.outputs.allFinite()) throw TransientPredictionError("the predicted outputs are not finite");
    if (!sensitivities) {
      t.prediction = std::move(p);
      return true;
    }
    t.sensitivities.assign(channels_.size(), Eigen::MatrixXd());
    for (std::size_t b = 0; b < channels_.size(); ++b) {
      if (!t.fitted(static_cast<int>(b))) continue;
      const auto row = std::find(p.channels.begin(), p.channels.end(), t.recorded[b]) - p.channels.begin();
      if (row >= static_cast<Eigen::Index>(p.channels.size()))
        throw std::logic_error(fmt::format("the prediction has no '{}' output", t.recorded[b]));
      Eigen::MatrixXd j = p.sensitivities[row];
      if (j.rows() != samples || j.cols() != l || !j.allFinite())
        throw TransientPredictionError(fmt::format("the sensitivities of '{}' are not finite", t.recorded[b]));
      for (int k = 0; k < l; ++k) j.col(k) *= scale_[estimated_[k]];
      t.sensitivities[b] = std::move(j);
    }
    return true;
  } catch (const TransientPredictionError& e) {  // no prediction at these parameters: the fit drops it
    t.error = e.what();
    return false;
  }
}

const std::string& FitProblem::error(int experiment) const { return experiments_.at(experiment).error; }

bool FitProblem::Solve(const std::vector<double>& theta, bool allow_drop, int iteration,
                       const std::function<void(const FitProgress&)>& progress) {
  // Experiments are independent: solved on `threads` threads (progress is reported as they start).
  std::vector<std::optional<std::string>> failure(experiments_.size());
  std::mutex progress_mutex;
  ParallelFor(experiment_count(), threads_, [&](int a) {
    Experiment& s = experiments_[a];
    if (!s.active) return;
    if (progress) {
      const std::lock_guard lock(progress_mutex);
      progress({iteration, a + 1, experiment_count(), NAN});
    }
    try {
      const std::vector<double> at = model_.AtExperiment(theta, s.data->Conditions());
      s.solution = s.solution.n == s.n() ? s.solver->Solve(s.input, at, &s.solution) : FirstSolve(s, at);
    } catch (const PeriodicSolverError& e) {
      failure[a] = e.what();
    }
  });
  for (TransientExperiment& t : transients_) {
    if (!t.active) continue;
    if (PredictTransient(t, theta, false)) continue;
    if (!allow_drop) return false;
    t.active = false;
    t.dropped_at_start = true;
    t.sensitivities.clear();
    spdlog::warn("{} experiment '{}': no prediction at the starting values ({}); left out until the parameters improve",
                 t.data->kind, t.data->label, t.error);
  }
  for (std::size_t a = 0; a < experiments_.size(); ++a) {
    if (!failure[a]) continue;
    if (!allow_drop) return false;
    Experiment& s = experiments_[a];
    s.active = false;
    s.dropped_at_start = true;
    s.error = *failure[a];
    spdlog::warn("experiment '{}': no periodic solution at the starting values ({}); left out until the "
                 "parameters improve",
                 s.data->label, s.error);
  }
  return true;
}

bool FitProblem::Readmit(const std::vector<double>& theta) {
  bool readmitted = false;
  for (Experiment& s : experiments_) {
    if (s.active || !s.dropped_at_start) continue;
    try {
      s.solution = FirstSolve(s, model_.AtExperiment(theta, s.data->Conditions()));
      s.active = true;
      s.error.clear();
      s.sensitivity_rows.clear();
      readmitted = true;
      spdlog::info("experiment '{}' has a periodic solution again; back in the fit", s.data->label);
    } catch (const PeriodicSolverError&) {
    }
  }
  for (TransientExperiment& t : transients_) {
    if (t.active || !t.dropped_at_start || !PredictTransient(t, theta, false)) continue;
    t.active = true;
    t.error.clear();
    t.sensitivities.clear();
    readmitted = true;
    spdlog::info("{} experiment '{}' has a prediction again; back in the fit", t.data->kind, t.data->label);
  }
  return readmitted;
}

PeriodicSolution FitProblem::FirstSolve(Experiment& s, const std::vector<double>& theta) const {
  // From the measured stroke when that fits, else cold.
  const auto measured = stroke_driven_ ? MeasuredStrokeStart(model_, *stroke_driven_, *s.data, s.input, theta,
                                                             s.n(), SolverOptions(options_, model_))
                                       : std::nullopt;
  if (measured) {
    try {
      return s.solver->Solve(s.input, theta, &*measured);
    } catch (const PeriodicSolverError& e) {
      spdlog::debug("experiment '{}': no solution from the measured stroke ({}); cold start", s.data->label, e.what());
    }
  }
  return s.solver->Solve(s.input, theta);
}

FitProblem::Saved FitProblem::Snapshot() const {
  Saved saved;
  for (const Experiment& s : experiments_) {
    saved.solutions.push_back(s.solution);
    saved.inputs.push_back(s.estimate ? s.estimate->xi : Eigen::VectorXd());
  }
  for (const TransientExperiment& t : transients_) saved.transient_outputs.push_back(t.prediction.outputs);
  return saved;
}

void FitProblem::Restore(Saved saved) {
  for (std::size_t a = 0; a < experiments_.size(); ++a) {
    Experiment& s = experiments_[a];
    s.solution = std::move(saved.solutions[a]);
    if (s.estimate && s.estimate->xi != saved.inputs[a]) {
      s.estimate->xi = std::move(saved.inputs[a]);
      s.UpdateInput();
    }
  }
  for (std::size_t k = 0; k < transients_.size() && k < saved.transient_outputs.size(); ++k)
    transients_[k].prediction.outputs = std::move(saved.transient_outputs[k]);
}

bool FitProblem::estimates_inputs() const {
  return std::any_of(experiments_.begin(), experiments_.end(), [](const Experiment& s) { return s.estimate.has_value(); });
}

void FitProblem::StepInputs(const std::vector<Eigen::VectorXd>& steps, double fraction) {
  for (std::size_t a = 0; a < experiments_.size() && a < steps.size(); ++a) {
    Experiment& s = experiments_[a];
    if (!s.estimate || steps[a].size() != s.estimate->xi.size()) continue;
    s.estimate->xi += fraction * steps[a];
    s.UpdateInput();
  }
}

double FitProblem::InputLogPrior() const {
  double value = 0.0;
  for (const Experiment& s : experiments_)
    if (s.estimate && s.active) value -= 0.5 * s.estimate->xi.squaredNorm();
  return value;
}

ResidualSums FitProblem::Evaluate() const {
  const int all = static_cast<int>(channels_.size());
  const int nc = periodic_channels_;
  ResidualSums e;
  e.sum_squares.assign(all, 0.0);
  e.counts.assign(all, 0);
  e.input_dof.assign(all, 0.0);
  for (const TransientExperiment& t : transients_) {
    if (!t.active) continue;
    for (int b = nc; b < all; ++b) {
      if (!t.fitted(b)) continue;
      const Eigen::VectorXd r = t.Residual(b);
      e.sum_squares[b] += r.squaredNorm();
      e.counts[b] += r.size();
    }
  }
  for (const Experiment& s : experiments_) {
    if (!s.active) continue;
    for (int b = 0; b < nc; ++b) {
      if (!s.channel_fitted[b]) continue;
      const Eigen::VectorXd r = s.Residual(channels_[b], output_row_[b]);
      e.sum_squares[b] += r.squaredNorm();
      e.counts[b] += r.size();
      e.input_dof[b] += s.InputDof(b);
    }
  }
  for (double v : e.sum_squares) e.finite = e.finite && std::isfinite(v);
  return e;
}

bool FitProblem::RefreshInputSensitivities(Experiment& s, const std::vector<double>& at, LinearisationMode mode) {
  const int nc = periodic_channels_;
  if (mode.reuse && static_cast<int>(s.estimate->sensitivity_rows.size()) == nc) return false;
  // d(outputs)/d xi: a forward solve per coefficient with eq. 14's factorisation.
  const auto sens = s.solver->InputSensitivities(s.solution, at, s.estimate->directions, mode.exact);
  if (sens.empty()) {
    // A predictor without input sensitivities (transient integration): the input stays as it is.
    spdlog::warn("experiment '{}': the predictor has no input sensitivities; its input is not estimated",
                 s.data->label);
    s.estimate.reset();
    return false;
  }
  s.estimate->sensitivity_rows.assign(nc, Eigen::MatrixXd());
  s.estimate->gram.assign(nc, Eigen::MatrixXd());
  for (int b = 0; b < nc; ++b) {
    if (!s.channel_fitted[b]) continue;
    const Eigen::MatrixXd& jc = s.estimate->sensitivity_rows[b] = s.SampleColumns(sens[output_row_[b]]);
    Eigen::MatrixXd& g = s.estimate->gram[b];
    g.setZero(jc.cols(), jc.cols());
    g.selfadjointView<Eigen::Lower>().rankUpdate(jc.transpose());
  }
  return true;
}

bool FitProblem::RefreshParameterSensitivities(Experiment& s, const std::vector<double>& at,
                                               LinearisationMode mode) const {
  const int nc = periodic_channels_;
  if (mode.reuse && static_cast<int>(s.sensitivity_rows.size()) == nc) return false;
  const int l = static_cast<int>(estimated_.size());
  const auto sens = s.solver->OutputSensitivities(s.solution, at, estimated_, mode.exact);
  s.sensitivity_rows.assign(nc, Eigen::MatrixXd());
  for (int b = 0; b < nc; ++b) {
    if (!s.channel_fitted[b]) continue;
    Eigen::MatrixXd& j = s.sensitivity_rows[b] = s.SampleColumns(sens[output_row_[b]]);
    for (int k = 0; k < l; ++k) j.col(k) *= scale_[estimated_[k]];
  }
  return true;
}

NormalEquations FitProblem::Linearise(const std::vector<double>& theta, const std::vector<double>& variance,
                                      LinearisationMode mode) {
  const int l = static_cast<int>(estimated_.size());
  const int nc = periodic_channels_;
  NormalEquations eq;
  eq.information.setZero(l, l);
  eq.gradient.setZero(l);
  // Per experiment on `threads` threads, summed in experiment order (the same result for any count).
  std::vector<Eigen::MatrixXd> hs(experiments_.size(), Eigen::MatrixXd::Zero(l, l));
  eq.experiment_gradient.assign(experiments_.size(), Eigen::VectorXd::Zero(l));
  std::vector<Eigen::MatrixXd> ns(experiments_.size(), Eigen::MatrixXd::Zero(l, l));
  if (mode.inputs && estimates_inputs()) eq.inputs.assign(experiments_.size(), NuisanceBlock());
  ParallelFor(experiment_count(), threads_, [&](int a) {
    Experiment& s = experiments_[a];
    if (!s.active) return;
    const std::vector<double> at = model_.AtExperiment(theta, s.data->Conditions());
    const bool inputs_fresh = mode.inputs && s.estimate && RefreshInputSensitivities(s, at, mode);
    const bool with_estimate = mode.inputs && s.estimate;
    const bool parameters_fresh = RefreshParameterSensitivities(s, at, mode);
    // The gradient's noise from the input's: J^T W P dy = (P^T W J)^T dy on the grid (P the
    // interpolation to the phases), so the output weights P^T W J give it by one adjoint solve.
    // (Harmonics the fit estimates carry their noise through their elimination instead.)
    const int n = s.n();
    const int estimated_harmonics = with_estimate ? s.estimate->harmonics : -1;
    const bool with_input = mode.input_noise && s.data->input_harmonic_variance > 0 &&
                            std::any_of(s.data->input_harmonics.begin(), s.data->input_harmonics.end(),
                                        [&](int h) { return h > estimated_harmonics && h < n; });
    std::vector<Eigen::MatrixXd> weights;
    if (with_input) weights.assign(s.solution.channels.size(), Eigen::MatrixXd::Zero(n, l));
    NuisanceBlock block;
    if (with_estimate) {
      const Eigen::Index k = s.estimate->xi.size();
      // The products over the samples only when a factor changed (reused sensitivities: the same).
      if (inputs_fresh || parameters_fresh || static_cast<int>(s.estimate->coupling.size()) != nc) {
        s.estimate->coupling.assign(nc, Eigen::MatrixXd());
        for (int b = 0; b < nc; ++b)
          if (s.channel_fitted[b])
            s.estimate->coupling[b].noalias() = s.sensitivity_rows[b].transpose() * s.estimate->sensitivity_rows[b];
      }
      block.information = Eigen::MatrixXd::Identity(k, k);
      block.coupling = Eigen::MatrixXd::Zero(l, k);
      block.gradient = -s.estimate->xi;
    }
    for (int b = 0; b < nc; ++b) {
      if (!s.channel_fitted[b]) continue;
      const Eigen::MatrixXd& j = s.sensitivity_rows[b];
      const Eigen::VectorXd r = s.SampleVector(s.Residual(channels_[b], output_row_[b]));
      const double w = 1.0 / variance[b];
      hs[a].noalias() += w * (j.transpose() * j);  // the weight folds into the product (no temporary)
      eq.experiment_gradient[a].noalias() += w * (j.transpose() * r);
      if (with_input)
        for (int k = 0; k < l; ++k) weights[output_row_[b]].col(k) += s.GridWeights(j.col(k), n) / variance[b];
      if (with_estimate) {
        block.information.triangularView<Eigen::Lower>() += w * s.estimate->gram[b];
        block.coupling += w * s.estimate->coupling[b];
        block.gradient.noalias() += w * (s.estimate->sensitivity_rows[b].transpose() * r);
      }
    }
    if (with_estimate) {
      Eigen::MatrixXd full = block.information.selfadjointView<Eigen::Lower>();
      block.information = std::move(full);
      // The residual degrees of freedom the estimate takes per channel: E[r^T W r] at the truth is
      // count - tr(A^-1 J_c^T W J_c) (linearised; A includes the prior). Formed from the small
      // k x k products, not from the phases (L^-1 J_c^T costs the phase count times k^2).
      const Eigen::LLT<Eigen::MatrixXd> llt(block.information);
      s.estimate->dof.assign(nc, 0.0);
      for (int b = 0; b < nc; ++b) {
        if (!s.channel_fitted[b]) continue;
        const Eigen::MatrixXd g = s.estimate->gram[b].selfadjointView<Eigen::Lower>();
        s.estimate->dof[b] = llt.solve(g).trace() / variance[b];
      }
      eq.inputs[a] = std::move(block);
    }
    if (with_input) {
      const Eigen::MatrixXd gradient = s.solver->InputGradients(s.solution, at, weights);
      if (gradient.size() > 0)
        ns[a] = InputNoiseCovariance(*s.data, gradient, estimated_harmonics);
    }
  });
  // Drops: their sensitivities from the predictor (IDAS forward sensitivities), residuals of the
  // samples weighted by the drop channels' own variances.
  for (TransientExperiment& t : transients_) {
    Eigen::MatrixXd h = Eigen::MatrixXd::Zero(l, l);
    Eigen::VectorXd g = Eigen::VectorXd::Zero(l);
    if (t.active) {
      if ((!mode.reuse || mode.exact || t.sensitivities.empty()) && !PredictTransient(t, theta, true))
        throw EstimationError(fmt::format("{} experiment '{}': no sensitivities at the current parameters: {}",
                                             t.data->kind, t.data->label, t.error));
      for (int b = nc; b < static_cast<int>(channels_.size()); ++b) {
        if (!t.fitted(b)) continue;
        const Eigen::MatrixXd& j = t.sensitivities[b];
        h.noalias() += j.transpose() * j / variance[b];
        g.noalias() += j.transpose() * t.Residual(b) / variance[b];
      }
    }
    hs.push_back(std::move(h));
    ns.push_back(Eigen::MatrixXd::Zero(l, l));
    eq.experiment_gradient.push_back(std::move(g));
  }
  for (std::size_t a = 0; a < hs.size(); ++a) {
    eq.information += hs[a];
    eq.gradient += eq.experiment_gradient[a];
  }
  if (mode.input_noise) {
    eq.input_noise.setZero(l, l);
    for (const auto& m_a : ns) eq.input_noise += m_a;
    eq.experiment_input_noise = ns;
  }
  eq.experiment_information = std::move(hs);
  return eq;
}

FitProblem::GainGradient FitProblem::GainGradients(const std::string& channel, const std::vector<double>& theta,
                                                   const std::vector<double>& variance) {
  const int nc = periodic_channels_;
  GainGradient g;
  g.parameters.setZero(static_cast<Eigen::Index>(estimated_.size()));
  g.inputs.resize(experiments_.size());
  const int output = static_cast<int>(std::find(channels_.begin(), channels_.begin() + nc, channel) - channels_.begin());
  const bool input = channel == model_.input_channel();
  if (output == nc && !input) return g;  // a drop's channel, or not in this fit
  std::vector<Eigen::VectorXd> parameters(experiments_.size());
  std::atomic<bool> covered = true;
  ParallelFor(experiment_count(), threads_, [&](int a) {
    const Experiment& s = experiments_[a];
    parameters[a].setZero(g.parameters.size());
    if (!s.active || static_cast<int>(s.sensitivity_rows.size()) != nc) return;
    // d(outputs on the grid)/dg when the input reads (1 + g) times the truth.
    std::vector<Eigen::MatrixXd> along_input;
    if (input) {
      const Eigen::Map<const Eigen::VectorXd> u(s.solution.input.values.data(), s.n());
      along_input = s.solver->InputSensitivities(s.solution, model_.AtExperiment(theta, s.data->Conditions()),
                                                 Eigen::MatrixXd(u), true);
      if (along_input.empty()) {
        covered = false;
        return;
      }
    }
    const bool with_estimate = s.estimate && static_cast<int>(s.estimate->sensitivity_rows.size()) == nc;
    if (with_estimate) g.inputs[a].setZero(s.estimate->xi.size());
    for (int b = 0; b < nc; ++b) {
      if (!s.channel_fitted[b]) continue;
      Eigen::VectorXd de = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(s.phase_count()));  // d(residual)/dg
      if (b == output) {
        const GridChannel& measured = s.data->channels.at(channels_[b]);
        de = measured.mean.array() - measured.reading_offset;  // what the gain scales
      }
      if (input) de -= s.AtPhases(along_input[output_row_[b]].col(0));
      const Eigen::VectorXd rows = s.SampleVector(de);
      parameters[a].noalias() += s.sensitivity_rows[b].transpose() * rows / variance[b];
      if (with_estimate) g.inputs[a].noalias() += s.estimate->sensitivity_rows[b].transpose() * rows / variance[b];
    }
  });
  for (const Eigen::VectorXd& p : parameters) g.parameters += p;
  g.covered = covered;
  return g;
}

FitProblem::NoiseRatios FitProblem::NoiseRatioStatistics() const {
  const int all = static_cast<int>(channels_.size());
  const int nc = periodic_channels_;
  // Each experiment adds S_a = chi2(N_a) / (chi2(d_a) / d_a) with the model right (d_a: its noise
  // estimate's degrees of freedom, infinite for a transient's): var(S_a) = 2 N_a + 2 N_a^2 / d_a.
  std::vector<double> squares(all, 0.0), count(all, 0.0), variance(all, 0.0);
  for (const TransientExperiment& t : transients_) {
    if (!t.active) continue;
    for (int b = nc; b < all; ++b) {
      if (!t.fitted(b)) continue;
      const double noise = t.data->channels.at(t.recorded[b]).noise_variance;
      if (!(noise > 0)) continue;
      const Eigen::VectorXd r = t.Residual(b);
      const double n = static_cast<double>(r.size());
      squares[b] += r.squaredNorm() / noise;
      count[b] += n;
      variance[b] += 2.0 * n;
    }
  }
  for (const Experiment& s : experiments_) {
    if (!s.active) continue;
    for (int b = 0; b < nc; ++b) {
      const auto it = s.data->channels.find(channels_[b]);
      if (!s.channel_fitted[b] || it == s.data->channels.end() || !(it->second.mean_noise_variance > 0)) continue;
      const double n = static_cast<double>(s.phase_count()) - s.InputDof(b);
      const double noise_dof = static_cast<double>(s.phase_count()) * static_cast<double>(s.data->periods - 1);
      squares[b] += s.Residual(channels_[b], output_row_[b]).squaredNorm() / it->second.mean_noise_variance;
      count[b] += n;
      variance[b] += 2.0 * n + (noise_dof > 0 ? 2.0 * n * n / noise_dof : 0.0);
    }
  }
  NoiseRatios out{std::vector<double>(all, NAN), std::vector<double>(all, NAN)};
  for (int b = 0; b < all; ++b)
    if (count[b] > 0) {
      out.ratio[b] = squares[b] / count[b];
      out.sd[b] = std::sqrt(variance[b]) / count[b];
    }
  return out;
}

void FitProblem::Summarise(const ResidualSums& sums, const std::vector<double>& variance, const NoiseRatios& ratios,
                           FitSummary& summary) {
  const int all = static_cast<int>(channels_.size());
  const int nc = periodic_channels_;
  for (int b = 0; b < all; ++b) {
    FitChannel c;
    c.name = channels_[b];
    c.variance = variance[b];
    c.rms = sums.counts[b] > 0 ? std::sqrt(sums.sum_squares[b] / sums.counts[b]) : NAN;
    double noise = 0.0;
    int count = 0;
    for (const Experiment& s : experiments_) {
      const auto it = s.data->channels.find(channels_[b]);
      if (b < nc && s.active && s.channel_fitted[b] && it != s.data->channels.end() &&
          std::isfinite(it->second.mean_noise_variance)) {
        noise += it->second.mean_noise_variance;
        ++count;
      }
    }
    for (const TransientExperiment& t : transients_)
      if (t.active && t.fitted(b) && std::isfinite(t.data->channels.at(t.recorded[b]).noise_variance)) {
        noise += t.data->channels.at(t.recorded[b]).noise_variance;
        ++count;
      }
    c.noise_floor_variance = count > 0 ? noise / count : NAN;
    c.noise_ratio = ratios.ratio[b];
    c.noise_ratio_sd = ratios.sd[b];
    c.noise_floor_limit = NoiseFloorLimit(ratios.sd[b], static_cast<std::size_t>(all));
    summary.channels.push_back(c);
  }
  for (Experiment& s : experiments_) {
    ExperimentFit f;
    f.label = s.data->label;
    f.group = s.data->group;
    f.session = s.data->session;
    f.frequency = s.data->frequency;
    f.amplitude = s.data->amplitude;
    f.static_position = s.data->static_position;
    f.session_time = s.data->session_time;
    f.converged = s.active;
    f.error = s.error;
    f.phases = s.data->phases;
    for (const auto& [name, channel] : s.data->channels) f.measured[name] = channel.mean;
    if (!s.active)
      summary.warnings.push_back(
          fmt::format("experiment '{}': no periodic solution ({}); left out of the fit", s.data->label, s.error));
    for (int b = 0; b < nc; ++b) {
      ChannelStatistics st;
      st.channel = channels_[b];
      st.fitted = s.channel_fitted[b] && s.active;
      const auto it = s.data->channels.find(channels_[b]);
      if (s.active && it != s.data->channels.end()) {
        const Eigen::VectorXd r = s.Residual(channels_[b], output_row_[b]);
        f.residual[channels_[b]] = r;
        f.noise_variance[channels_[b]] = it->second.mean_noise_variance;
        SetResidualStatistics(r, st);
        st.input_dof = s.InputDof(b);
        st.noise_ratio = r.squaredNorm() / (std::max(1.0, r.size() - st.input_dof) * it->second.mean_noise_variance);
      }
      f.channels.push_back(st);
    }
    if (s.active) {
      f.solution = std::move(s.solution);
      f.solution.solver_state = {};  // a result holds values only; the factorisation is megabytes
    }
    summary.experiments.push_back(std::move(f));
  }
  for (const TransientExperiment& t : transients_) {
    TransientExperimentFit f;
    f.label = t.data->label;
    f.session = t.data->session;
    f.kind = t.data->kind;
    f.drop_mass = t.data->drop_mass;
    f.impact_velocity = t.data->impact_velocity;
    f.converged = t.active;
    f.error = t.error;
    f.time = t.data->time;
    if (!t.active)
      summary.warnings.push_back(
          fmt::format("{} experiment '{}': no prediction ({}); left out of the fit", f.kind, f.label, t.error));
    for (int b = nc; b < all; ++b) {
      if (!t.fitted(b)) continue;
      const std::string& channel = t.recorded[b];
      const TransientChannel& recorded = t.data->channels.at(channel);
      ChannelStatistics st;
      st.channel = channel;
      st.fitted = t.active;
      f.measured[channel] = recorded.samples;
      f.noise_variance[channel] = recorded.noise_variance;
      if (t.active) {
        f.predicted[channel] = t.Predicted(b);
        const Eigen::VectorXd r = t.Residual(b);
        SetResidualStatistics(r, st);
        st.noise_ratio = r.squaredNorm() / (static_cast<double>(r.size()) * recorded.noise_variance);
      }
      f.channels.push_back(st);
    }
    summary.transient_experiments.push_back(std::move(f));
  }
}

}  // namespace strut::ident
