// Drop-test prediction from an identified model (method.md "Drop test"): the model integrated in
// mass-load mode (TransientSimulator), the figures a landing-gear engineer reads off a drop
// (peak force, maximum stroke, rebound, the static end value and the time the gas takes to cool to
// it), and the fitted parameters' uncertainty carried to each figure by linearisation.
// docs/drop-prediction.md defines every figure and the interval.
#pragma once

#include <Eigen/Core>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "strut/daq/session.h"
#include "strut/ident/model.h"
#include "strut/sim/transient.h"

namespace strut::sim {

//! A drop, predicted or recorded, from contact on. Strokes are true strokes (the stroke sensor's
//! zero removed), pressures absolute.
struct DropTrace {
  std::vector<double> time;         //!< s, from contact
  std::vector<double> stroke;       //!< m, compression-positive
  std::vector<double> force;        //!< N, axle force
  std::vector<double> pressure;     //!< Pa absolute; empty when there is none
  std::vector<double> temperature;  //!< K; empty when there is none
};

//! The figures of one drop (docs/drop-prediction.md). Times from contact; NaN when not defined.
struct DropFigures {
  double peak_force = NAN;          //!< N, largest axle force
  double time_of_peak_force = NAN;  //!< s
  double max_stroke = NAN;          //!< m, deepest stroke
  double time_of_max_stroke = NAN;  //!< s
  double rebound = NAN;             //!< m, max_stroke minus the least stroke after it
  double peak_pressure = NAN;       //!< Pa absolute (NaN without pressure)
  double final_stroke = NAN;        //!< m, at the end of the record
  //! s, from contact until the stroke stays within the settle band of final_stroke: when the
  //! stroke has come to its end value within the record (the gas cooling, friction creeping).
  double time_to_final = NAN;
  //! m, the static equilibrium under M g at ambient temperature: where the stroke ends once the
  //! gas has cooled (a model property; NaN for a record, which has no model).
  double static_stroke = NAN;
  //! s, from contact until the stroke stays within the settle band of static_stroke (NaN: not
  //! within the record).
  double time_to_static = NAN;
};

//! One figure's name (the JSON key) and unit, in the order of FigureValues.
struct DropFigureName {
  const char* name;
  const char* unit;
};
const std::vector<DropFigureName>& DropFigureNames();
std::vector<double> FigureValues(const DropFigures& figures);

//! The figures of a trace. `static_stroke` (m) is the reference of time_to_static (NaN: not
//! computed); `settle_band` is relative to it (and to final_stroke for time_to_final). Peaks are refined between samples by a parabola
//! through the largest sample and its neighbours. Throws std::invalid_argument on an empty trace
//! or channels of different lengths.
DropFigures MeasureDrop(const DropTrace& trace, double static_stroke, double settle_band);

//! A recorded drop experiment as a trace: the stroke minus `stroke_offset` (the fit's stroke
//! sensor zero theta12), the pressure made absolute. Throws daq::SessionError naming the
//! experiment and channel when it is not a drop or lacks stroke or force.
DropTrace DropTraceFromRecord(const daq::Experiment& experiment, double stroke_offset);

//! Which mass moves in the drop (docs/drop-prediction.md, "The moving mass").
enum class DropMovingMass {
  kDroppedAlone,      //!< the dropped mass alone; theta1 (the shaker's moving mass) stays on the ground
  kDroppedWithTheta1  //!< the dropped mass carries theta1 (a rig whose carriage moves with the damper)
};
std::string_view ToString(DropMovingMass m);
//! "dropped" or "dropped+theta1"; nullopt for anything else.
std::optional<DropMovingMass> DropMovingMassFrom(std::string_view text);

struct DropPredictionOptions {
  DropMovingMass moving_mass = DropMovingMass::kDroppedAlone;
  double duration = 30.0;      //!< s simulated from contact (0 < duration <= 3600)
  double output_rate = 1000.0;  //!< Hz, samples of the trace (the figures' time resolution before refinement)
  //! IDA's relative tolerance. 1e-7 keeps the figures' integration error far below their
  //! intervals and the 1 % that matters in a drop, at a fraction of the reference 1e-9's cost.
  double rtol = 1e-7;
  double settle_band = 0.01;  //!< time_to_static: within this fraction of the static stroke
  bool intervals = true;      //!< carry the covariance to the figures (2 runs per estimated parameter)
  double level = 0.95;        //!< two-sided probability of the intervals
  bool IsValid(std::string* error) const;
};

//! A figure's uncertainty from the fitted parameters' (NaN when not computed).
struct FigureUncertainty {
  double sd = NAN;
  double lower = NAN, upper = NAN;  //!< value -+ z sd for the options' level
};

struct DropPrediction {
  DropLoad load;
  DropTrace trace;
  DropFigures figures;
  //! Per figure (DropFigureNames order); empty when intervals were not asked for.
  std::vector<FigureUncertainty> uncertainty;
  //! The parameters carried to the intervals (keys) and d figure / d parameter (figures x those).
  std::vector<std::string> interval_parameters;
  Eigen::MatrixXd gradient;
  //! Estimated parameters left out of the intervals, each with why (no sd, the run failed, ...).
  std::vector<std::string> interval_notes;
  int simulations = 0;         //!< transient runs made (1 + 2 per parameter with intervals)
  long ida_steps = 0;          //!< of the nominal run
  double nominal_seconds = 0.0;  //!< wall time of the nominal run
  double seconds = 0.0;        //!< wall time of everything
};

//! Predicts a drop of `mass` (kg) at `impact_velocity` (m/s) with `model` (integrated in its
//! force-input form) at `theta`. By default the rig's fixture mass theta1 is set to 0: on a drop rig
//! the moving mass is the dropped mass alone (as SimulatedRig::RunDrop); with
//! options.moving_mass kDroppedWithTheta1 theta1 moves with it (and enters the intervals). `estimated` (positions in
//! theta) and `covariance` (their posterior covariance) give the intervals: each figure's gradient
//! by central differences over +- one sd of each parameter, sd^2 = g' C g. Throws
//! std::invalid_argument for bad arguments, TransientError when the nominal run fails.
DropPrediction PredictDrop(const ident::Model& model, std::span<const double> theta, double mass,
                           double impact_velocity, const std::vector<int>& estimated, const Eigen::MatrixXd& covariance,
                           const DropPredictionOptions& options = {});

//! What-if: the parameters `theta` with those at the positions of `factors` multiplied, and the
//! posterior covariance of the `estimated` positions with each scaled parameter's row and column
//! multiplied as well, so that its sd scales with its value.
struct ScaledParameters {
  std::vector<double> theta;
  Eigen::MatrixXd covariance;
};
ScaledParameters ScaleParameters(std::span<const double> theta, const std::vector<int>& estimated,
                                 const Eigen::MatrixXd& covariance, const std::map<int, double>& factors);

//! A drop predicted from a fit with what-if factors (positions in theta -> factors, may be
//! empty), and when any is given the fit as it is, without intervals, to compare with.
struct WhatIfDrop {
  DropPrediction predicted;
  std::optional<DropPrediction> unscaled;
};
//! PredictDrop of the scaled parameters (ScaleParameters) and, with factors, of `theta` as it is.
WhatIfDrop PredictDropWhatIf(const ident::Model& model, std::span<const double> theta, double mass,
                             double impact_velocity, const std::vector<int>& estimated,
                             const Eigen::MatrixXd& covariance, const std::map<int, double>& factors,
                             const DropPredictionOptions& options);

//! The drop experiment of `session` (read from `path`) to compare with: the one labelled `label`,
//! or without a label the session's only drop. Throws std::invalid_argument naming the path and
//! the experiment when there is none, several, or the labelled one is not a drop.
const daq::Experiment& FindDropExperiment(const daq::Session& session, const std::string& label,
                                          const std::string& path);

//! A recorded drop measured as a prediction is: its trace with the stroke less the fitted stroke
//! sensor zero (theta12 of `fitted`, 0 when the model has none), and its figures, settling
//! measured against `static_stroke` (the prediction's: a record has no model; its own
//! static_stroke is NaN).
struct MeasuredDrop {
  DropTrace trace;
  DropFigures figures;
};
//! Throws daq::SessionError as DropTraceFromRecord does.
MeasuredDrop MeasureRecordedDrop(const daq::Experiment& drop, const ident::ParameterSet& fitted, double static_stroke,
                                 double settle_band);

//! What a term the fitted model lacks does to a drop: the truth simulated with and without it.
struct MissingPhysics {
  std::string term;  //!< e.g. "end-stop"
  //! Per figure (DropFigureNames order): (with - without) / |without|; empty when not separable.
  std::vector<double> relative_change;
  //! In words: the figures it changes by more than the threshold ("max_stroke -2.1 %, ..."),
  //! "no figure by more than ..." or why it could not be separated.
  std::string affects;
};

//! For every term of `truth_composition` that `fitted` lacks: the truth's drop (parameters by key
//! from `truth_parameters`) with and without the term, and the figures it changes by more than
//! `threshold` (relative). A term of the base that cannot be removed without changing other
//! parameters' meaning (heat-exchange, gas-solubility, ...) is named with the figures such physics
//! drives by construction. `options.intervals` is ignored.
std::vector<MissingPhysics> AttributeMissingPhysics(const std::string& truth_composition,
                                                    const ident::ParameterSet& truth_parameters,
                                                    const ident::Model& fitted, double mass, double impact_velocity,
                                                    const DropPredictionOptions& options, double threshold = 0.005);

}  // namespace strut::sim
