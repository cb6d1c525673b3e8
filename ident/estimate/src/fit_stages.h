// The stages of Estimator::Fit, split as Ceres splits its solver: the scaled parameterisation the
// stages share, the minimizer (the staged Gauss-Newton iteration of eqs. 18, 19), the covariance
// at the final iterate, and the diagnostics read from it. Each takes the fit problem (the
// evaluator) and returns a value; none keeps state between fits.
#pragma once

#include <Eigen/Dense>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "strut/ident/bard.h"
#include "strut/ident/estimator.h"
#include "strut/ident/fit_problem.h"

namespace strut::ident::internal {

//! The estimated parameters in scaled units x_k = theta_i / scale_i (i = estimated[k]), which keeps
//! the normal equations well conditioned; the fixed parameters keep their values.
struct ScaledParameters {
  std::vector<int> estimated;  //!< positions of the estimated parameters
  std::vector<double> scale;   //!< per parameter
  std::vector<double> fixed;   //!< every parameter's starting value; the fixed ones never change

  ScaledParameters(const ParameterSet& initial, const std::vector<int>& estimated);
  int size() const { return static_cast<int>(estimated.size()); }
  Eigen::VectorXd Scaled(const std::vector<double>& values) const;
  std::vector<double> Unscaled(const Eigen::VectorXd& x) const;
  //! The user's priors (mean: the starting value) and the physical ranges, scaled; an open end
  //! keeps a millionth of the parameter's scale inside it.
  ScaledPriors Priors(const ParameterSet& initial, const std::vector<ParameterChoice>& choices) const;
  ScaledBounds Bounds(const ParameterSet& initial) const;
};

//! Why the minimizer stopped.
enum class TerminationType {
  kConvergence,    //!< the undamped step is below the tolerance, or the objective stopped changing at it
  kNoImprovement,  //!< no step along the damped direction improved the objective, far from the optimum
  kSingular,       //!< the normal equations became singular
  kMaxIterations,  //!< the iteration limit came first
};

struct MinimizerSummary {
  TerminationType termination = TerminationType::kMaxIterations;
  std::string message;  //!< the termination in words, empty on convergence
  int iterations = 0;
  std::vector<double> theta;  //!< the final iterate, every parameter
  ResidualSums residuals;     //!< at `theta`
  bool estimating_inputs = false;  //!< the inputs' coefficients were estimated in the last round
  std::vector<FitIteration> history;
  bool converged() const { return termination == TerminationType::kConvergence; }
};

//! The staged Gauss-Newton iteration from `theta` (every experiment already solved there): stage 1
//! the channel variances with bias correction, stage 2 the damped Bard step with a halving line
//! search inside the bounds, the estimated inputs joining near the measured inputs' optimum.
MinimizerSummary Minimize(FitProblem& problem, const ScaledParameters& parameters, const ScaledPriors& priors,
                          const ScaledBounds& bounds, const EstimatorOptions& options, std::vector<double> theta,
                          const std::function<void(const FitProgress&)>& progress);

//! The uncertainty at the final iterate, per parameter position (NaN when fixed).
struct CovarianceSummary {
  std::vector<double> sd;
  std::vector<double> input_noise_sd_factor;  //!< empty when the input's noise is not propagated
  std::vector<double> misfit_sd_factor;       //!< empty at the noise floor
  std::vector<double> calibration_sd;         //!< empty without a calibration
  std::map<std::string, double> calibration;  //!< the gains held, by channel
  Eigen::MatrixXd correlation;                //!< among the estimated parameters
  std::vector<ExperimentContribution> contributions;
  //! Near-null directions of the information (indices into the estimated parameters).
  std::vector<std::vector<int>> undetermined;
  std::vector<std::string> warnings;  //!< the misfit widening, in words
};

//! Posterior covariance without the damping prior, with exact sensitivities and the measured
//! inputs' noise; above the noise floor each sd widened to what the experiments' disagreement
//! implies (the sandwich over experiments); the transducers' calibration added; what each experiment
//! contributes.
//! `variance` and `ratio`: the channels' variances and noise ratios at the minimum; `misfit`: some
//! channel lies above its noise floor (NoiseFloorLimit), so the sd's are widened.
CovarianceSummary EstimateCovariance(FitProblem& problem, const ScaledParameters& parameters,
                                     const ScaledPriors& priors, const EstimatorOptions& options,
                                     const MinimizerSummary& minimum, const std::vector<double>& variance,
                                     const std::vector<double>& ratio, bool misfit);

//! What the covariance says the data cannot tell: parameters whose interval is their prior's,
//! undetermined directions, strongly correlated groups; one warning each.
std::vector<std::string> CovarianceDiagnostics(const CovarianceSummary& covariance, const ParameterSet& initial,
                                               const std::vector<ParameterChoice>& choices,
                                               const std::vector<int>& estimated);

}  // namespace strut::ident::internal
