// The multi-experiment modified Bayesian (Bard) estimator on periodic equilibrium states
// (paper section 2.2, method.md): one parameter vector, all experiments fitted at once.
#pragma once

#include <Eigen/Dense>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "strut/ident/experiment_data.h"
#include "strut/ident/model.h"
#include "strut/ident/parameters.h"
#include "strut/ident/periodic.h"
#include "strut/ident/transient_fit.h"

namespace strut::ident {

//! How one parameter takes part in the fit.
struct ParameterChoice {
  bool estimate = false;
  std::optional<double> prior_sd;  //!< a normal prior (mean: the initial value) on an estimated parameter
};

struct EstimatorOptions {
  //! Least grid points per period (a grid holds every recorded sample phase) and difference scheme
  //! of the periodic solver; 0 and unset: by the model's causality (DefaultGridPoints, DefaultScheme).
  int n = 0;
  std::optional<Scheme> scheme;
  //! Periods of time marching before the periodic solver's first Newton solve of an experiment
  //! (PeriodicSolverOptions::start_up_periods). The damper default 2 settles friction; a weakly
  //! nonlinear oscillator needs none (Newton from the quasi-static guess converges in a few steps).
  int start_up_periods = 2;
  //! Points of the coarse grid the first solve of an experiment starts on
  //! (PeriodicSolverOptions::coarse_points); 0 starts on the full grid (multisine inputs).
  int coarse_points = 50;
  //! Threads that solve the experiments of one iterate side by side (each has its own solver);
  //! 0: one per core. The sums run in experiment order, so the fit is the same for any count.
  int threads = 1;
  //! Gauss-Newton iterations before giving up.
  int max_iterations = 40;
  //! Converged when every parameter step is below this fraction of its posterior sd.
  double step_tolerance = 1e-3;
  //! The paper's prior reset to the current iterate (eq. 20, unreadable in the OCR; our choice):
  //! sd = damping_relative_sd * |theta_i|. It damps like Levenberg-Marquardt; it is widened after
  //! a full step and narrowed after a halved one. Never part of the reported uncertainty.
  double damping_relative_sd = 0.3;
  //! Errors in variables: the posterior covariance also carries the measured input's noise (each
  //! experiment's input series: the noise of its kept Fourier coefficients, from the spread between
  //! periods), propagated through the model to the outputs and on to the estimate.
  bool input_noise = true;
  //! Errors in variables done properly: the measured input's Fourier coefficients (the mean and the
  //! cosine and sine of harmonics 1 .. `input_harmonics`, capped below the averaged record's Nyquist)
  //! are estimated with the parameters, each with the prior N(measured value, its noise variance from
  //! the spread between periods). Per experiment they are nuisance parameters, eliminated from the
  //! normal equations by the Schur complement; the posterior then carries their uncertainty exactly
  //! (the `input_noise` sandwich is left to the kept harmonics above `input_harmonics`). The force
  //! locates a velocity reversal the truncated stroke series misplaces (servo actuator: the loop's
  //! reaction at the reversal sits below one coefficient's noise). Empty: on for stroke input, off
  //! for force input.
  std::optional<bool> estimate_input;
  int input_harmonics = 20;
  //! Step halvings per iteration when the objective does not improve.
  int max_halvings = 12;
  //! The posterior at the end (sd, correlations, contributions: a linearisation with exact
  //! sensitivities and the input's noise). Off for a fit whose estimate alone is used (the refits
  //! of cross-validation); the estimate does not depend on it.
  bool uncertainty = true;
  //! Output channels to fit; empty: the outputs of the causality (stroke and pressure for force
  //! input, force and pressure for stroke input; y for a generic oscillator driven by u).
  std::vector<std::string> channels;
  //! Relative sd of each transducer's gain, by channel name (0.002: a load cell calibrated to 0.2 %
  //! of reading). The posterior adds what such gain errors move the estimate by (linearised), so
  //! intervals hold the calibration's uncertainty beside the noise's; the fitted outputs and the
  //! input are covered (FitProblem::GainGradients), a drop's channels and channels the fit does not
  //! use are not. Empty: the noise alone (SessionFitOptions sets the lab default, kLabGainSd).
  std::map<std::string, double> gain_sd;
  //! How outputs and sensitivities are predicted; empty: the periodic solver with `scheme`.
  //! (`strut bench identify` plugs in transient integration to compare.)
  std::function<std::unique_ptr<PeriodicPredictor>(const Model&)> predictor;
  //! How transient (drop) experiments are predicted, with their sensitivities (sim::DropPredictorFactory).
  //! Empty: drop experiments given to the fit are left out with a warning (ident cannot integrate them).
  TransientPredictorFactory transient_predictor;
  bool IsValid(std::string* error) const;
};

//! Transducer gains' relative sd (EstimatorOptions::gain_sd, FitSummary::calibration) in words:
//! "force 0.2 %, pressure 0.2 %, stroke 0.1 %".
std::string GainSdText(const std::map<std::string, double>& gain_sd);

//! Residual statistics of one channel of one experiment (paper Figs. 8 and 11).
struct ChannelStatistics {
  std::string channel;
  double mean = 0.0;         //!< mean residual (measured - predicted)
  double sd = 0.0;           //!< standard deviation of the residual
  double rms = 0.0;
  double noise_ratio = NAN;  //!< residual mean square / noise variance of the averaged data (about 1: fits to the noise)
  bool fitted = true;        //!< false when excluded for a data defect
  //! Residual degrees of freedom the estimated input takes from this channel (errors in variables,
  //! EstimatorOptions::estimate_input): tr(A^-1 J_c^T W J_c). The expected residual sum of squares
  //! at the truth is (count - input_dof) noise variances, and `noise_ratio` is taken over that.
  double input_dof = 0.0;
};

struct ExperimentFit {
  std::string label, group, session;
  double frequency = 0.0, amplitude = 0.0, static_position = 0.0;
  double session_time = 0.0;  //!< ExperimentData::session_time
  bool converged = false;     //!< the periodic solution exists at the final parameters
  std::string error;          //!< why not
  std::vector<ChannelStatistics> channels;
  PeriodicSolution solution;  //!< at the final parameters (empty when not converged)
  std::vector<double> phases;                       //!< cyclic phases of the measured values
  std::map<std::string, Eigen::VectorXd> measured;  //!< every averaged measured channel at `phases`
  std::map<std::string, Eigen::VectorXd> residual;  //!< measured - predicted at `phases`, fitted channels
  std::map<std::string, double> noise_variance;     //!< of the averaged values, per fitted channel
};

//! A transient (drop) experiment of the fit: its residual statistics and its record beside the
//! prediction at the final parameters.
struct TransientExperimentFit {
  std::string label, session, kind;
  double drop_mass = 0.0, impact_velocity = 0.0;
  bool converged = false;  //!< predicted at the final parameters
  std::string error;       //!< why not
  //! Per fitted channel (`channel` is the recorded name, "stroke"); noise_ratio against the
  //! record's noise variance at rest.
  std::vector<ChannelStatistics> channels;
  std::vector<double> time;
  std::map<std::string, Eigen::VectorXd> measured;   //!< per fitted channel, SI (pressure absolute)
  std::map<std::string, Eigen::VectorXd> predicted;  //!< per fitted channel at the final parameters
  std::map<std::string, double> noise_variance;      //!< per fitted channel, per sample
};

//! What one experiment adds to the estimate (linearised at the final parameters, white noise at
//! the fit's channel variances, the misfit widening left out): docs/drop-prediction.md.
struct ExperimentContribution {
  std::string label;
  std::string kind;  //!< "periodic" or "drop"
  //! Per parameter (all of them; NaN when fixed): this experiment's share of the diagonal of the
  //! information J'WJ (the shares of all experiments sum to 1).
  std::vector<double> information_share;
  //! Per parameter: the posterior sd with this experiment left out (NaN when fixed, +inf when the
  //! others leave it undetermined). Over FitSummary::sd it is how much sharper this experiment makes it.
  std::vector<double> sd_without;
};

struct FitChannel {
  std::string name;
  double variance = 0.0;             //!< bias-corrected residual variance v_b = M_bb / (nN - l)
  double noise_floor_variance = NAN; //!< mean noise variance of the averaged data over the experiments
  double rms = 0.0;
  //! Pooled over the fitted experiments: sum of e^2 / s_a^2 over the count, s_a^2 each experiment's
  //! noise variance of the averaged data (about 1 at the noise floor; agrees with the per-experiment
  //! ratios, unlike variance / noise_floor_variance when the experiments' noise differs).
  double noise_ratio = NAN;
  //! The ratio's sampling sd with the model right (NoiseRatioSd), and the limit above which noise
  //! alone would put it only with probability kNoiseFloorFalseAlarm (NoiseFloorLimit).
  double noise_ratio_sd = NAN;
  double noise_floor_limit = NAN;
  //! The ratio at or above its limit (kNoiseFloorRatio where the limit is unknown).
  bool AboveNoiseFloor() const;
};

struct FitIteration {
  int iteration = 0;
  double objective = 0.0;  //!< log-likelihood at this iterate (channel variances at their estimates)
  double step = 1.0;       //!< step fraction accepted
  std::vector<double> values;
};

//! The noise floor is a test, not a number. With the model right, a channel's pooled noise ratio
//! (FitChannel::noise_ratio) is the ratio of two independent chi-square means: the residuals' (one
//! per averaged sample, less the fitted input's degrees of freedom) over the noise estimate's (each
//! experiment's spread between its P periods, n (P - 1) degrees of freedom per n samples). It
//! scatters around 1 with a sd that falls with the samples (0.016 for a standard matrix of 12,000
//! samples and 3 periods): a ratio of 1.12 there is seven sd above the floor, 1.03 is not.
//! A fit is at the floor when no channel lies further above 1 than noise puts it with probability
//! kNoiseFloorFalseAlarm, shared among the channels (Bonferroni).
inline constexpr double kNoiseFloorFalseAlarm = 1e-3;
//! The limit where the ratio's sampling sd is unknown (no experiment with two periods or more).
inline constexpr double kNoiseFloorRatio = 1.2;
//! Upper-tail standard normal quantile: z with P(Z > z) = p, for 0 < p < 1.
double UpperNormalQuantile(double p);
//! 1 + z sd with z = UpperNormalQuantile(kNoiseFloorFalseAlarm / channels); kNoiseFloorRatio when
//! `sd` is not finite. The normal approximation of the ratio's F distribution holds for the
//! thousands of samples of a matrix (its skew moves the limit by under 0.1 sd there).
double NoiseFloorLimit(double sd, std::size_t channels);

//! What a fit amounts to, in the order a user must hear it.
enum class FitVerdict {
  kAtNoiseFloor,     //!< converged, every fitted channel at the noise floor
  kAboveNoiseFloor,  //!< converged, but the model does not explain the data
  kNotConverged,
};
const char* ToString(FitVerdict verdict);  //!< "at-noise-floor", "above-noise-floor", "not-converged"

//! What the fit says of one parameter.
struct ParameterEstimate {
  bool estimated = false;
  std::optional<double> prior_sd;  //!< the fit's prior on it (ParameterChoice::prior_sd)
  double sd = NAN;  //!< posterior sd (NaN when fixed)
  //! sd over the sd from the output noise alone: what the measured input's noise adds (NaN when
  //! fixed, or when the input's noise is unknown or not propagated).
  double input_noise_sd_factor = NAN;
  //! Above the noise floor: how much the sd was widened for the misfit (ExperimentSandwich); NaN at
  //! the noise floor and when fixed.
  double misfit_sd_factor = NAN;
  //! What the transducers' calibration (EstimatorOptions::gain_sd) alone contributes to the sd (the
  //! sd includes it: sd^2 = the rest^2 + this^2); NaN without a calibration and when fixed.
  double calibration_sd = NAN;
};

//! Everything a fit found; BriefReport()/FullReport() for people, the fields for JSON and reports.
struct FitSummary {
  std::string model;
  bool converged = false;
  int iterations = 0;
  ParameterSet parameters;                  //!< final values
  std::vector<ParameterEstimate> estimates;  //!< per parameter, in the order of `parameters`
  //! The transducer gains it holds (channel: relative sd), the fitted outputs' and the input's; empty without.
  std::map<std::string, double> calibration;
  std::vector<int> estimated_positions;
  Eigen::MatrixXd correlation;       //!< among the estimated parameters
  std::vector<FitChannel> channels;
  std::vector<ExperimentFit> experiments;
  std::vector<TransientExperimentFit> transient_experiments;  //!< drops, in the order given
  //! Per experiment (periodic ones first, then the drops): what it adds (empty when nothing was estimated).
  std::vector<ExperimentContribution> contributions;
  double loglik = 0.0, aic = 0.0, bic = 0.0;
  long observations = 0;
  std::vector<std::string> warnings;
  std::vector<FitIteration> history;

  std::string BriefReport() const;
  std::string FullReport() const;
  //! Above the noise floor the intervals were widened for the misfit (ParameterEstimate::misfit_sd_factor).
  bool WidenedForMisfit() const;
  //! Parameter i's sd without the calibration's part (what the data and the model give).
  double NoiseSd(int i) const;
  bool IsSolutionUsable() const;
  FitVerdict Verdict() const;
  //! The verdict in one or two sentences: converged or not, at the noise floor or how far above it
  //! and where (experiments and channels), and what to do next.
  std::string VerdictText() const;
};

struct FitProgress {
  int iteration = 0;
  int experiment = 0, experiments = 0;  //!< experiment i of N being solved
  double objective = NAN;
};

//! What a fit of a unit nobody has characterised estimates: every parameter the shaker data can
//! determine (ParameterSpec::estimate_by_default) and the sizes and shapes of the composition's optional terms,
//! with the specs' default priors (the stroke zero: kStrokeZeroPriorSd). Known constants (gravity,
//! the ambient temperature, the fixed shapes of optional terms) stay at their values.
std::vector<ParameterChoice> DefaultChoices(const ParameterSet& parameters);
std::vector<ParameterChoice> DefaultChoices(const Model& model);

//! The paper's set (1 dof: theta4, theta6, theta7; 2 dof: theta4, theta6, theta16) plus the sensor
//! offsets theta11, theta12; for models that are not dampers, their defaults.
std::vector<ParameterChoice> PaperChoices(const ParameterSet& parameters);

//! Applies "--estimate": "theta4,theta6" (estimate these, fix the rest), "paper" (PaperChoices) or
//! empty / "default" (DefaultChoices). Named parameters keep their specs' default priors.
std::vector<ParameterChoice> ChoicesFromList(const ParameterSet& parameters, const std::string& list);

//! A fit that cannot proceed on its data: no experiment has a solution at the starting values,
//! or a drop has no sensitivities at the current parameters. A failure of the data and starting
//! values, not of the program: callers that fit many candidates note it and go on.
class EstimationError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class Estimator {
 public:
  Estimator(Model model, EstimatorOptions options = {});
  const Model& model() const { return model_; }

  //! Fits all experiments at once from `initial`. Experiments whose periodic solution fails at the
  //! start are reported by name and left out; the others still fit. `transients` (drops) are fitted
  //! beside the periodic ones when the options have a transient_predictor. Throws EstimationError
  //! when no experiment has a solution at the start, std::invalid_argument for mismatched input.
  FitSummary Fit(const std::vector<ExperimentData>& data, const ParameterSet& initial,
                 const std::vector<ParameterChoice>& choices, const std::vector<DataIssue>& issues = {},
                 const std::function<void(const FitProgress&)>& progress = {},
                 const std::vector<TransientExperimentData>& transients = {}) const;

 private:
  Model model_;
  EstimatorOptions options_;
};

}  // namespace strut::ident
