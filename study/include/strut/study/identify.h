// The estimator's figures (`strut bench identify`): the fit time of the standard matrix, the
// coverage of the reported 95 % intervals over noise realisations, and the same fit with
// predictions from transient integration to steady state instead of the periodic solver.
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "strut/daq/session.h"
#include "strut/ident/estimator.h"
#include "strut/ident/experiment_data.h"
#include "strut/ident/periodic.h"
#include "strut/sim/periodic_session.h"
#include "strut/sim/transient_predictor.h"
#include "strut/study/statistics.h"

namespace strut::study {

//! Calls and time of one fit's predictors (and the work of TransientPredictors).
struct PredictorTally {
  long solves = 0, cold_solves = 0, sensitivity_calls = 0, failures = 0;
  double solve_ms = 0.0, cold_ms = 0.0, sensitivity_ms = 0.0;
  sim::TransientPredictorStats transient;
};

using PredictorFactory = std::function<std::unique_ptr<ident::PeriodicPredictor>(const ident::Model&)>;

//! Periodic solvers with `scheme`.
PredictorFactory PeriodicFactory(ident::Scheme scheme);

//! One fit, timed over repeats.
struct TimedFit {
  ident::FitSummary fit;  //!< of the last run
  double ms = 0.0;        //!< median wall time of Estimator::Fit
  double cpu_ms = 0.0;    //!< median CPU time of the fitting thread
  PredictorTally tally;   //!< of the last run
  int runs = 0;
};

//! Fits `data` `repeats` times from `initial`, the predictors from `factory` counted and timed.
TimedFit TimeFit(const ident::Model& model, const std::vector<ident::ExperimentData>& data,
                 const ident::ParameterSet& initial, const std::vector<ident::ParameterChoice>& choices,
                 const PredictorFactory& factory, int n, int repeats, std::optional<bool> estimate_input = std::nullopt);

//! The bench's problem: 2 dof, the standard matrix, these three parameters estimated on n = 800.
inline constexpr int kIdentifyN = 800;
inline constexpr const char* kIdentifyEstimate = "theta4,theta6,theta16";
inline constexpr double kFitTargetMs = 50.0;  //!< the full fit's target, judged on the CPU time

//! The 2 dof defaults without a stroke offset: the truth of the simulated sessions.
ident::ParameterSet IdentifyTruth();

//! `truth` with every estimated parameter `off` (0.2: 20 %) too large.
ident::ParameterSet Off(const ident::ParameterSet& truth, const std::vector<ident::ParameterChoice>& choices,
                        double off);

// 1. The full fit of the standard matrix, both causalities, from the truth and from 20 % off.
struct FitTimeRow {
  ident::Causality causality = ident::Causality::kStrokeInput;
  bool from_truth = true;
  TimedFit timed;
  double worst_z = 0.0;  //!< max |estimate - truth| / sd
};
std::vector<FitTimeRow> MeasureFitTimes(const daq::Session& session, const ident::ParameterSet& truth, int repeats);

// 2. The calibration of the reported uncertainty: stroke input, started at the truth, backward2
// (the default scheme) and central4 (its discretisation error at n = 800 is negligible: the
// difference separates the scheme's bias from the uncertainty machinery itself).
struct SchemeCoverage {
  ident::Scheme scheme = ident::Scheme::kBackward2;
  long not_converged = 0;
  std::vector<std::pair<std::string, ZCoverage>> parameters;  //!< by key, in parameter order
  long pooled_inside = 0, pooled_total = 0;  //!< over every parameter (one fit's intervals are correlated)
  long jointly_inside = 0;                   //!< realisations with every interval holding the truth
};
struct CoverageStudy {
  int realisations = 0;
  double seconds = 0.0;  //!< wall time of every fit of both schemes
  sim::SensorNoise noise;
  std::pair<double, double> nominal_range95;  //!< where a calibrated interval's fraction falls (BinomialRange)
  std::vector<SchemeCoverage> schemes;
};
//! `realisations` noise realisations of the standard matrix; `stroke_noise` < 0: the simulated
//! rig's stroke noise (0 removes the input's noise).
CoverageStudy MeasureCoverage(const ident::ParameterSet& truth, int realisations, double stroke_noise);

// 3. The same fit with transient integration to steady state.
struct TransientSettings {
  double rtol = 1e-10, atol = 1e-2, steady = 1e-7, sensitivity = 1e-5;
  //! Predictor options that reach the periodic solver's accuracy on these fits (docs).
  sim::TransientPredictorOptions PredictorOptions() const;
};
struct TransientComparison {
  ident::Causality causality = ident::Causality::kStrokeInput;
  std::string experiments;  //!< the labels fitted
  double off = 0.0;         //!< the start: every estimated parameter this fraction too large
  sim::TransientPredictorOptions options;
  long estimated = 0;
  int repeats = 0;          //!< of the periodic fits; the transient fit runs once
  TimedFit backward2, central4, transient;
  std::string transient_error;  //!< why the transient fit failed (empty: it ran)
};
//! The fits of `labels` (empty: every experiment) from `off`, the measured inputs kept (transient
//! integration has no input sensitivities, so neither side estimates the input).
TransientComparison CompareWithTransient(const daq::Session& session, const ident::ParameterSet& truth,
                                         ident::Causality causality, double off, const std::string& labels,
                                         const TransientSettings& settings, int repeats);

}  // namespace strut::study
