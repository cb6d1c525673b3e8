#include "strut/study/identify.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>
#include <stdexcept>

#include "strut/rig/test_matrix.h"
#include "strut/study/cpu_time.h"

namespace strut::study {
namespace {

using Clock = std::chrono::steady_clock;

double MsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

//! Wraps a predictor to count and time its calls; two clock reads per call (microseconds
//! against milliseconds per solve).
class TallyingPredictor : public ident::PeriodicPredictor {
 public:
  TallyingPredictor(std::unique_ptr<ident::PeriodicPredictor> inner, PredictorTally* tally)
      : inner_(std::move(inner)), tally_(tally) {}
  ~TallyingPredictor() override {
    if (const auto* t = dynamic_cast<const sim::TransientPredictor*>(inner_.get())) tally_->transient += t->stats();
  }
  ident::PeriodicSolution Solve(const ident::PeriodicInput& input, std::span<const double> theta,
                                const ident::PeriodicSolution* warm_start) override {
    const auto start = Clock::now();
    try {
      ident::PeriodicSolution s = inner_->Solve(input, theta, warm_start);
      const double ms = MsSince(start);
      tally_->solve_ms += ms;
      ++tally_->solves;
      if (!warm_start) {
        tally_->cold_ms += ms;
        ++tally_->cold_solves;
      }
      return s;
    } catch (const ident::PeriodicSolverError&) {
      tally_->solve_ms += MsSince(start);
      ++tally_->failures;
      throw;
    }
  }
  std::vector<Eigen::MatrixXd> OutputSensitivities(const ident::PeriodicSolution& solution,
                                                   std::span<const double> theta,
                                                   std::span<const int> parameters, bool exact) override {
    const auto start = Clock::now();
    auto s = inner_->OutputSensitivities(solution, theta, parameters, exact);
    tally_->sensitivity_ms += MsSince(start);
    ++tally_->sensitivity_calls;
    return s;
  }
  Eigen::MatrixXd InputGradients(const ident::PeriodicSolution& solution, std::span<const double> theta,
                                 const std::vector<Eigen::MatrixXd>& output_weights) override {
    const auto start = Clock::now();
    auto s = inner_->InputGradients(solution, theta, output_weights);
    tally_->sensitivity_ms += MsSince(start);
    return s;
  }
  std::vector<Eigen::MatrixXd> InputSensitivities(const ident::PeriodicSolution& solution,
                                                  std::span<const double> theta, const Eigen::MatrixXd& directions,
                                                  bool exact) override {
    const auto start = Clock::now();
    auto s = inner_->InputSensitivities(solution, theta, directions, exact);
    tally_->sensitivity_ms += MsSince(start);
    return s;
  }

 private:
  std::unique_ptr<ident::PeriodicPredictor> inner_;
  PredictorTally* tally_;
};

std::vector<ident::ExperimentData> Subset(const std::vector<ident::ExperimentData>& data, const std::string& labels) {
  if (labels.empty()) return data;
  std::vector<ident::ExperimentData> out;
  for (const auto& d : data)
    if (labels.find(d.label) != std::string::npos) out.push_back(d);
  return out;
}

std::string Labels(const std::vector<ident::ExperimentData>& data) {
  std::string s;
  for (const auto& d : data) s += d.label;
  return s;
}

}  // namespace

PredictorFactory PeriodicFactory(ident::Scheme scheme) {
  return [scheme](const ident::Model& m) {
    ident::PeriodicSolverOptions o;
    o.scheme = scheme;
    return std::make_unique<ident::PeriodicSolver>(m, o);
  };
}

TimedFit TimeFit(const ident::Model& model, const std::vector<ident::ExperimentData>& data,
                 const ident::ParameterSet& initial, const std::vector<ident::ParameterChoice>& choices,
                 const PredictorFactory& factory, int n, int repeats, std::optional<bool> estimate_input) {
  TimedFit out;
  std::vector<double> times, cpu;
  for (int r = 0; r < repeats; ++r) {
    PredictorTally tally;
    ident::EstimatorOptions options;
    options.n = n;
    options.estimate_input = estimate_input;
    options.predictor = [&](const ident::Model& m) { return std::make_unique<TallyingPredictor>(factory(m), &tally); };
    const ident::Estimator estimator(model, options);
    const auto start = Clock::now();
    const double cpu_start = ThreadSeconds();
    ident::FitSummary fit = estimator.Fit(data, initial, choices);
    cpu.push_back(1e3 * (ThreadSeconds() - cpu_start));
    times.push_back(MsSince(start));
    out.fit = std::move(fit);
    out.tally = tally;
  }
  out.ms = Median(times);
  out.cpu_ms = Median(cpu);
  out.runs = repeats;
  return out;
}

ident::ParameterSet IdentifyTruth() {
  ident::ParameterSet truth = ident::Model::Build("2dof", ident::Causality::kStrokeInput).defaults();
  truth.set("theta12", 0.0);
  return truth;
}

ident::ParameterSet Off(const ident::ParameterSet& truth, const std::vector<ident::ParameterChoice>& choices,
                        double off) {
  ident::ParameterSet p = truth;
  for (int i = 0; i < p.size(); ++i)
    if (choices[i].estimate) p.values()[i] *= 1.0 + off;
  return p;
}

std::vector<FitTimeRow> MeasureFitTimes(const daq::Session& session, const ident::ParameterSet& truth, int repeats) {
  std::vector<FitTimeRow> rows;
  for (const ident::Causality causality : {ident::Causality::kStrokeInput, ident::Causality::kForceInput}) {
    const ident::Model model = ident::Model::Build("2dof", causality);
    const auto data = ident::PrepareExperiments(session, causality, kIdentifyN);
    const auto choices = ident::ChoicesFromList(model.defaults(), kIdentifyEstimate);
    for (const bool from_truth : {true, false}) {
      const ident::ParameterSet initial = from_truth ? truth : Off(truth, choices, 0.2);
      FitTimeRow row{causality, from_truth,
                     TimeFit(model, data, initial, choices, PeriodicFactory(ident::Scheme::kBackward2), kIdentifyN,
                             repeats),
                     0.0};
      const ident::FitSummary& fit = row.timed.fit;
      for (int i : fit.estimated_positions)
        row.worst_z = std::max(row.worst_z, std::abs(fit.parameters.value(i) - truth.value(i)) / fit.estimates[i].sd);
      rows.push_back(std::move(row));
    }
  }
  return rows;
}

CoverageStudy MeasureCoverage(const ident::ParameterSet& truth, int realisations, double stroke_noise) {
  CoverageStudy out;
  out.realisations = realisations;
  sim::PeriodicSessionOptions options;
  options.noise = {0.0, 0.0, 0.0};
  const daq::Session clean = sim::SimulatePeriodicSession("2dof", truth.values(), rig::StandardMatrix(), options);
  const ident::Model model = ident::Model::Build("2dof", ident::Causality::kStrokeInput);
  const auto choices = ident::ChoicesFromList(model.defaults(), kIdentifyEstimate);
  const std::vector<ident::Scheme> schemes = {ident::Scheme::kBackward2, ident::Scheme::kCentral4};
  std::vector<ident::Estimator> estimators;
  for (const ident::Scheme scheme : schemes) {
    ident::EstimatorOptions estimator_options;
    estimator_options.n = kIdentifyN;
    estimator_options.scheme = scheme;
    estimators.emplace_back(model, estimator_options);
  }
  if (stroke_noise >= 0) out.noise.stroke = stroke_noise;
  std::mt19937_64 rng(2024);
  std::vector<int> est;
  for (int i = 0; i < model.parameter_count(); ++i)
    if (choices[i].estimate) est.push_back(i);
  const std::size_t ns = schemes.size(), np = est.size();
  std::vector<std::vector<std::vector<double>>> z(ns, std::vector<std::vector<double>>(np));
  out.schemes.resize(ns);
  const auto start = Clock::now();
  for (int r = 0; r < realisations; ++r) {
    daq::Session noisy = clean;
    sim::AddSensorNoise(noisy, out.noise, rng);
    const auto data = ident::PrepareExperiments(noisy, model.causality(), kIdentifyN);
    for (std::size_t a = 0; a < ns; ++a) {
      const ident::FitSummary fit = estimators[a].Fit(data, truth, choices);
      out.schemes[a].not_converged += !fit.converged;
      bool all = true;
      for (std::size_t k = 0; k < np; ++k) {
        const double zk = (fit.parameters.value(est[k]) - truth.value(est[k])) / fit.estimates[est[k]].sd;
        z[a][k].push_back(zk);
        all = all && std::abs(zk) <= kZ95;
      }
      out.schemes[a].jointly_inside += all;
    }
  }
  out.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  out.nominal_range95 = BinomialRange(realisations, 0.95);
  for (std::size_t a = 0; a < ns; ++a) {
    SchemeCoverage& s = out.schemes[a];
    s.scheme = schemes[a];
    for (std::size_t k = 0; k < np; ++k) {
      const ZCoverage c = SummariseZ(z[a][k]);
      s.pooled_inside += c.inside;
      s.pooled_total += c.total;
      s.parameters.emplace_back(truth.spec(est[k]).key(), c);
    }
  }
  return out;
}

sim::TransientPredictorOptions TransientSettings::PredictorOptions() const {
  sim::TransientPredictorOptions o;
  o.integrator.rtol = rtol;
  o.integrator.atol_factor = atol;
  o.integrator.max_steps = 20'000'000;  // the 2 Hz experiments near full compression need millions
  o.steady.tol = 1.0;
  o.steady.relative_floor = steady;
  o.steady.periods_max = 5000;
  o.sensitivity_relative_tol = sensitivity;
  o.sensitivity_error_control = false;  // steps by the state alone: 20-40 % cheaper, estimates unchanged
  return o;
}

TransientComparison CompareWithTransient(const daq::Session& session, const ident::ParameterSet& truth,
                                         ident::Causality causality, double off, const std::string& labels,
                                         const TransientSettings& settings, int repeats) {
  TransientComparison out;
  out.causality = causality;
  out.off = off;
  out.repeats = repeats;
  out.options = settings.PredictorOptions();
  const ident::Model model = ident::Model::Build("2dof", causality);
  const auto choices = ident::ChoicesFromList(model.defaults(), kIdentifyEstimate);
  const auto data = Subset(ident::PrepareExperiments(session, causality, kIdentifyN), labels);
  out.experiments = Labels(data);
  out.estimated = std::count_if(choices.begin(), choices.end(), [](const auto& c) { return c.estimate; });
  const ident::ParameterSet initial = Off(truth, choices, off);
  const sim::TransientPredictorOptions transient_options = out.options;
  const PredictorFactory transient_factory = [transient_options](const ident::Model& m) {
    return std::make_unique<sim::TransientPredictor>(m, transient_options);
  };
  out.backward2 =
      TimeFit(model, data, initial, choices, PeriodicFactory(ident::Scheme::kBackward2), kIdentifyN, repeats, false);
  out.central4 =
      TimeFit(model, data, initial, choices, PeriodicFactory(ident::Scheme::kCentral4), kIdentifyN, repeats, false);
  try {
    out.transient = TimeFit(model, data, initial, choices, transient_factory, kIdentifyN, 1, false);
  } catch (const std::runtime_error& e) {  // no steady state or sensitivities anywhere (PeriodicSolverError)
    out.transient_error = e.what();
  }
  return out;
}

}  // namespace strut::study
