// The evaluator of a multi-experiment fit: every experiment's periodic solution at a parameter
// vector, the residuals of the fitted channels, their sensitivities (eqs. 14, 15) and the normal
// equations of eq. 19. The Bard iteration (estimator.h) and the uncertainty (covariance.h) are
// built on it; so are cross-validation and the starting-value checks. It owns the experiments'
// solvers and solutions (state), so one FitProblem serves one fit at a time.
#pragma once

#include <Eigen/Dense>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "strut/ident/bard.h"
#include "strut/ident/experiment_data.h"
#include "strut/ident/model.h"
#include "strut/ident/periodic.h"
#include "strut/ident/transient_fit.h"

namespace strut::ident {

struct EstimatorOptions;
struct FitSummary;
struct FitProgress;

//! Residual sums of one evaluation, per fitted channel over the active experiments.
struct ResidualSums {
  std::vector<double> sum_squares;
  std::vector<long> counts;
  //! Residual degrees of freedom the estimated inputs take per channel (ChannelStatistics::input_dof).
  std::vector<double> input_dof;
  bool finite = true;
  //! Log-likelihood with each channel's variance at its maximum-likelihood value M_bb / count.
  double LogLikelihood() const;
  //! Bias-corrected channel variances of eq. 18, v_b = M_bb / (count_b - l - input_dof_b).
  std::vector<double> Variances(int estimated) const;
};

//! Eq. 19's sums at one iterate, in scaled parameters (theta_i / scale_i).
struct NormalEquations {
  Eigen::MatrixXd information;  //!< sum J^T W J
  Eigen::VectorXd gradient;     //!< sum J^T W e
  //! The scaled-gradient covariance that the measured inputs' noise causes (errors in variables:
  //! sum over each input's noisy Fourier coefficients c of var(c) q_c q_c^T, q_c = J^T W dy/dc);
  //! empty unless asked for.
  Eigen::MatrixXd input_noise;
  //! Per experiment, its share of `gradient` (zero for inactive experiments); the periodic
  //! experiments first, then the transient ones.
  std::vector<Eigen::VectorXd> experiment_gradient;
  //! Per experiment (same order), its share of `information`.
  std::vector<Eigen::MatrixXd> experiment_information;
  //! Per experiment (same order), its share of `input_noise` (empty unless asked for).
  std::vector<Eigen::MatrixXd> experiment_input_noise;
  //! Per experiment, the block of its estimated input's coefficients (errors in variables,
  //! EstimatorOptions::estimate_input; empty where the input is not estimated): eliminated by the
  //! Bard step and the posterior (bard.h).
  std::vector<NuisanceBlock> inputs;
};

//! How Linearise computes sensitivities.
struct LinearisationMode {
  bool exact = false;        //!< sensitivities at the solution itself (else the carried factorisation may serve)
  bool reuse = false;        //!< the previous call's sensitivities where an experiment has them (modified Gauss-Newton)
  bool input_noise = false;  //!< also NormalEquations::input_noise (one adjoint solve per parameter and experiment)
  //! also NormalEquations::inputs where the fit estimates the input (a forward solve per coefficient)
  bool inputs = true;
};

class FitProblem {
 public:
  //! `estimated`: positions of the estimated parameters; `scale`: per parameter (all of them) the
  //! size the sensitivities are scaled by. Throws std::invalid_argument for data that do not suit
  //! the model (grid size, channels).
  //! `transients`: drop experiments, predicted by the options' transient_predictor (left out with a
  //! warning without one); their channels follow the periodic ones in channels().
  FitProblem(const Model& model, const EstimatorOptions& options, const std::vector<ExperimentData>& data,
             const std::vector<DataIssue>& issues, std::vector<int> estimated, std::vector<double> scale,
             const std::vector<TransientExperimentData>& transients = {});
  ~FitProblem();
  FitProblem(const FitProblem&) = delete;
  FitProblem& operator=(const FitProblem&) = delete;

  const std::vector<std::string>& channels() const { return channels_; }
  int experiment_count() const;  //!< periodic experiments
  int transient_count() const;   //!< transient experiments in the fit
  int active_count() const;      //!< experiments of either kind with a solution
  //! Labels of all experiments in the order of NormalEquations::experiment_gradient, and their kinds.
  std::vector<std::pair<std::string, std::string>> experiment_labels() const;
  //! Why an experiment has no solution (empty: it has one).
  const std::string& error(int experiment) const;
  //! Warnings found while setting up (missing channels, data defects).
  const std::vector<std::string>& warnings() const { return warnings_; }

  //! Solves every active experiment at `theta`, warm-started from its current solution. With
  //! `allow_drop`, experiments without a solution are named, left out and retried by Readmit;
  //! without it, any failure returns false (Snapshot and Restore undo a trial).
  bool Solve(const std::vector<double>& theta, bool allow_drop, int iteration = 0,
             const std::function<void(const FitProgress&)>& progress = {});
  //! Experiments left out at the start that have a solution at `theta` now come back in.
  bool Readmit(const std::vector<double>& theta);
  //! The current solutions and estimated inputs, to undo a rejected trial with Restore.
  struct Saved {
    std::vector<PeriodicSolution> solutions;
    std::vector<Eigen::VectorXd> inputs;
    std::vector<Eigen::MatrixXd> transient_outputs;
  };
  Saved Snapshot() const;
  void Restore(Saved saved);

  //! Whether any experiment's input is estimated (errors in variables, EstimatorOptions::estimate_input).
  bool estimates_inputs() const;
  //! Moves the estimated inputs by `fraction` of the Bard step's nuisance steps (one per experiment,
  //! in units of the coefficients' prior sd); the next Solve uses them.
  void StepInputs(const std::vector<Eigen::VectorXd>& steps, double fraction);
  //! The estimated inputs' log prior density, -1/2 sum ((c - measured) / sd)^2 (0 when none).
  double InputLogPrior() const;
  //! Residual sums of the current solutions.
  ResidualSums Evaluate() const;
  //! Eq. 19's sums at `theta` (the current solutions) with channel `variance`s.
  NormalEquations Linearise(const std::vector<double>& theta, const std::vector<double>& variance,
                            LinearisationMode mode);

  //! What a transducer gain error does to eq. 19's sums at the optimum: the gradient d(sum J^T W e)/dg
  //! of the parameters, and per experiment its estimated input's share d(J_c^T W e)/dg (to eliminate
  //! as the Bard step does), for a `channel` reading (1 + g) times the truth. A fitted output's gain
  //! adds g y to its residuals (y the reading the gain scales); the input's gain scales the measured
  //! input, and with it the estimated one (its coefficients, their prior sd, the kept harmonics
  //! above: in units of that sd the input on the grid is u (1 + g)), so it moves every fitted output
  //! by g du along u: one forward input sensitivity per experiment. From the sensitivities of the last
  //! Linearise at `theta` (call it first, exact, with inputs). `covered` false: the channel is neither
  //! fitted nor the input, or the predictor has no input sensitivities (a drop's channel is not covered).
  struct GainGradient {
    bool covered = false;
    Eigen::VectorXd parameters;
    std::vector<Eigen::VectorXd> inputs;  //!< per periodic experiment; empty where no input is estimated
  };
  GainGradient GainGradients(const std::string& channel, const std::vector<double>& theta,
                             const std::vector<double>& variance);

  //! Per fitted channel: `ratio`, the pooled residual mean square over each experiment's noise
  //! variance of the averaged data, sum_a sum_mu e^2 / s_a^2 over the count (about 1 at the noise
  //! floor; NaN where no experiment knows its noise), and `sd`, its sampling sd with the model
  //! right: the residuals' chi-square mean and each experiment's noise estimate (its phases times
  //! periods less one degrees of freedom; a transient's noise counts as known).
  struct NoiseRatios {
    std::vector<double> ratio, sd;
  };
  NoiseRatios NoiseRatioStatistics() const;
  //! Fills the summary's channel and experiment statistics (and moves the solutions into it).
  //! `ratios`: NoiseRatioStatistics() of the same solutions.
  void Summarise(const ResidualSums& sums, const std::vector<double>& variance, const NoiseRatios& ratios,
                 FitSummary& summary);

 private:
  struct Experiment;
  struct TransientExperiment;
  //! Predicts transient experiment `t` at `theta` (with the estimated parameters' sensitivities when
  //! `sensitivities`); false with its error set when the predictor fails.
  bool PredictTransient(TransientExperiment& t, const std::vector<double>& theta, bool sensitivities) const;
  //! The first solve of an experiment: from the measured stroke when that fits, else cold.
  PeriodicSolution FirstSolve(Experiment& experiment, const std::vector<double>& theta) const;
  // The sensitivities Linearise needs, recomputed unless `mode` reuses current ones; true when
  // recomputed. Without input sensitivities from the predictor the experiment's input estimate is dropped.
  // `at`: the parameters at the experiment's session time (Model::AtExperiment).
  bool RefreshInputSensitivities(Experiment& experiment, const std::vector<double>& at, LinearisationMode mode);
  bool RefreshParameterSensitivities(Experiment& experiment, const std::vector<double>& at,
                                     LinearisationMode mode) const;
  const Model& model_;
  const EstimatorOptions& options_;
  std::vector<std::string> channels_;
  std::vector<int> output_row_;
  std::vector<int> estimated_;
  std::vector<double> scale_;
  std::vector<Experiment> experiments_;
  std::vector<TransientExperiment> transients_;
  int periodic_channels_ = 0;  //!< channels_[0, periodic_channels_) are the periodic experiments'
  std::vector<std::string> warnings_;
  std::optional<Model> stroke_driven_;
  int threads_ = 1;
};

}  // namespace strut::ident
