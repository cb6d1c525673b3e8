#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "fit_stages.h"

namespace strut::ident::internal {

ScaledParameters::ScaledParameters(const ParameterSet& initial, const std::vector<int>& estimated_positions)
    : estimated(estimated_positions), scale(initial.size()), fixed(initial.values()) {
  for (int i = 0; i < initial.size(); ++i)
    scale[i] = std::max({std::abs(fixed[i]), initial.spec(i).typical_size(), 1e-300});
}

Eigen::VectorXd ScaledParameters::Scaled(const std::vector<double>& values) const {
  Eigen::VectorXd x(size());
  for (int k = 0; k < size(); ++k) x[k] = values[estimated[k]] / scale[estimated[k]];
  return x;
}

std::vector<double> ScaledParameters::Unscaled(const Eigen::VectorXd& x) const {
  std::vector<double> values = fixed;
  for (int k = 0; k < size(); ++k) values[estimated[k]] = x[k] * scale[estimated[k]];
  return values;
}

ScaledPriors ScaledParameters::Priors(const ParameterSet& initial, const std::vector<ParameterChoice>& choices) const {
  ScaledPriors priors{Eigen::VectorXd::Zero(size()), Scaled(initial.values())};
  for (int k = 0; k < size(); ++k) {
    const int i = estimated[k];
    if (choices[i].prior_sd) priors.precision[k] = std::pow(scale[i] / *choices[i].prior_sd, 2);
  }
  return priors;
}

ScaledBounds ScaledParameters::Bounds(const ParameterSet& initial) const {
  ScaledBounds bounds{Eigen::VectorXd::Constant(size(), -INFINITY), Eigen::VectorXd::Constant(size(), INFINITY)};
  for (int k = 0; k < size(); ++k) {
    const int i = estimated[k];
    const PhysicalRange& range = initial.spec(i).range;
    bounds.lower[k] = (range.lower + (range.lower_open ? 1e-6 * scale[i] : 0.0)) / scale[i];
    bounds.upper[k] = (range.upper - (range.upper_open ? 1e-6 * scale[i] : 0.0)) / scale[i];
  }
  return bounds;
}

namespace {

// Frozen sensitivities (modified Gauss-Newton): they change with the parameters relative to their
// size, so after a step below this fraction of every parameter (scaled units) they are within
// about that fraction, inside the few percent the steps tolerate.
constexpr double kFrozenSensitivityStep = 0.01;
constexpr double kFrozenInputStep = 0.1;
// Estimated inputs converge when their steps are below this fraction of their sd (given the
// parameters): the parameters' step allows for the inputs' pending one (Schur complement), so the
// inputs' tolerance only sets how close the residuals are to their optimum.
constexpr double kInputStepTolerance = 0.1;
// The first round only has to bring the joint problem within its Gauss-Newton range: within a
// tenth of an sd of the first round's optimum (the joint optimum lies 0.3-1.7 sd from it on drawn
// units) the inputs join at once instead of after the first round has converged to 1e-3 sd. At
// 1 sd a restart from 30 % off can end in a neighbouring optimum of the joint problem.
constexpr double kJoinInputsInSd = 0.1;

// One iteration's line search: halve until the objective improves (the trial kept inside the
// physical ranges).
struct LineSearchResult {
  bool accepted = false;
  double lambda = 1.0;   //!< the step fraction tried last (accepted when `accepted`)
  Eigen::VectorXd taken;  //!< the scaled step taken
  double gain = 0.0;      //!< the objective's rise
};

// The minimizer's state between iterations: the iterate, its residuals and objective, and the
// modified Gauss-Newton's memory (damping, frozen sensitivities, whether the inputs are estimated).
class GaussNewton {
 public:
  GaussNewton(FitProblem& problem, const ScaledParameters& parameters, const ScaledPriors& priors,
              const ScaledBounds& bounds, const EstimatorOptions& options, std::vector<double> theta,
              const std::function<void(const FitProgress&)>& progress)
      : problem_(problem), parameters_(parameters), priors_(priors), bounds_(bounds), options_(options),
        progress_(progress), damping_sd_(options.damping_relative_sd) {
    out_.theta = std::move(theta);
    x_ = parameters_.Scaled(out_.theta);
    out_.residuals = problem_.Evaluate();
    // With estimated inputs (errors in variables) the objective also has their prior.
    objective_ = Objective(out_.residuals, x_);
    out_.history.push_back({0, objective_, 0.0, out_.theta});
  }

  MinimizerSummary Run();

 private:
  double Objective(const ResidualSums& sums, const Eigen::VectorXd& x) const {
    return sums.LogLikelihood() + priors_.LogDensity(x) + problem_.InputLogPrior();
  }
  // Errors in variables (estimated inputs) in two rounds: the parameters first with every input at
  // its thresholded series, then parameters and inputs together from there. Far from the optimum
  // the inputs would take up the model's misfit (the friction's sign can flip through sharpness 0),
  // near it they take up what the series truncates. True when the fit goes on with the inputs
  // estimated; `sensitivities_current`: the last Linearise was at this iterate, so the joint
  // problem's first one keeps its parameter sensitivities and adds the inputs'.
  bool EstimateInputsNow(bool sensitivities_current, int iteration) {
    if (out_.estimating_inputs || !problem_.estimates_inputs()) return false;
    spdlog::debug("fit iteration {}: within reach with the measured inputs; now estimating them too", iteration + 1);
    out_.estimating_inputs = true;
    reuse_sensitivities_ = sensitivities_current;
    // From the optimum with the measured inputs the joint problem starts within its Gauss-Newton
    // range: almost undamped (sd 30 in scaled units and in the inputs' prior sd; the line search
    // still halves). Reset to 0.3, the damping held the inputs' first steps to a tenth.
    damping_sd_ = std::max(damping_sd_, 100.0 * options_.damping_relative_sd);
    return true;
  }
  LineSearchResult LineSearch(const BardStep& step, int iteration);
  void Stop(TerminationType type, std::string message = {}) {
    out_.termination = type;
    out_.message = std::move(message);
    stopped_ = true;
  }

  FitProblem& problem_;
  const ScaledParameters& parameters_;
  const ScaledPriors& priors_;
  const ScaledBounds& bounds_;
  const EstimatorOptions& options_;
  const std::function<void(const FitProgress&)>& progress_;
  MinimizerSummary out_;
  Eigen::VectorXd x_;
  double objective_ = 0.0;
  double damping_sd_;
  bool reuse_sensitivities_ = false;
  bool stopped_ = false;
};

LineSearchResult GaussNewton::LineSearch(const BardStep& step, int iteration) {
  LineSearchResult r;
  for (int halving = 0; halving <= options_.max_halvings; ++halving, r.lambda *= 0.5) {
    const Eigen::VectorXd trial_x = bounds_.Project(x_ + r.lambda * step.step);
    const std::vector<double> trial = parameters_.Unscaled(trial_x);
    FitProblem::Saved saved = problem_.Snapshot();
    problem_.StepInputs(step.nuisance_step, r.lambda);
    if (problem_.Solve(trial, false, iteration + 1, progress_)) {
      const ResidualSums e = problem_.Evaluate();
      const double value = Objective(e, trial_x);
      if (e.finite && value >= objective_ - 1e-12 * std::abs(objective_)) {
        r.taken = trial_x - x_;
        r.gain = value - objective_;
        spdlog::debug("fit iteration {}: loglik {:.6g} (+{:.3g}), step {}, damping sd {:.3g}, undamped step {:.3g} sd{}",
                      iteration + 1, value, value - objective_, r.lambda, damping_sd_, step.NewtonInSd(),
                      out_.estimating_inputs ? fmt::format(", input step {:.3g} sd", step.nuisance_step_in_sd) : "");
        out_.theta = trial;
        x_ = trial_x;
        out_.residuals = e;
        objective_ = value;
        r.accepted = true;
        return r;
      }
    }
    problem_.Restore(std::move(saved));
  }
  return r;
}

MinimizerSummary GaussNewton::Run() {
  const int l = parameters_.size();
  if (l == 0) Stop(TerminationType::kConvergence);
  int iteration = 0;
  for (; iteration < options_.max_iterations && !stopped_; ++iteration) {
    // Stage 1 (eq. 18): channel variances with bias correction; stage 2 (eq. 19): the step.
    const NormalEquations eq = problem_.Linearise(out_.theta, out_.residuals.Variances(l),
                                                  {false, reuse_sensitivities_, false, out_.estimating_inputs});
    const BardStep step = ComputeBardStep(eq.information, eq.gradient, x_, priors_, bounds_, damping_sd_, eq.inputs);
    if (!step.finite) {
      Stop(TerminationType::kSingular, "estimator: the normal equations became singular; stopped");
      break;
    }
    // At the optimum to the tolerance already (the undamped step: a damped one can be tiny far from
    // the optimum, in a narrow valley): no trial solves (at the optimum the line search could only
    // halve through rounding, one round of solves per halving).
    if (step.NewtonInSd() < options_.step_tolerance && step.nuisance_step_in_sd < kInputStepTolerance) {
      if (EstimateInputsNow(true, iteration)) continue;
      Stop(TerminationType::kConvergence);
      break;
    }
    if (!out_.estimating_inputs && step.NewtonInSd() < kJoinInputsInSd && EstimateInputsNow(true, iteration)) continue;
    const LineSearchResult search = LineSearch(step, iteration);
    if (progress_) progress_({iteration + 1, 0, problem_.experiment_count(), objective_});
    out_.history.push_back({iteration + 1, objective_, search.accepted ? search.lambda : 0.0, out_.theta});
    if (!search.accepted) {
      // No improvement along the damped step: at the optimum to the accuracy the solutions allow.
      if (step.NewtonInSd() < 0.1) {
        if (EstimateInputsNow(false, iteration)) continue;
        Stop(TerminationType::kConvergence);
      } else {
        Stop(TerminationType::kNoImprovement, "estimator: no improvement along the Gauss-Newton step; stopped");
      }
      break;
    }
    // Experiments without a solution at the start may have one now: bring them back in.
    if (problem_.Readmit(out_.theta)) {
      out_.residuals = problem_.Evaluate();
      objective_ = Objective(out_.residuals, x_);
      out_.history.back().objective = objective_;
      reuse_sensitivities_ = false;
      damping_sd_ = std::max(damping_sd_ * 0.25, 1e-6);
      continue;
    }
    damping_sd_ = search.lambda == 1.0 ? std::min(damping_sd_ * 2.0, 1e3) : std::max(damping_sd_ * 0.25, 1e-6);
    // At the rounding floor: the objective no longer changes beyond rounding (1e-10 of itself: the
    // residual sums of tens of thousands of samples carry about that) while the undamped step is
    // within a tenth of an sd. The sensitivities' accuracy, not the optimum, then limits the step,
    // and the line search would go on accepting steps that change nothing.
    if (std::abs(search.gain) < 1e-10 * std::abs(objective_) && step.NewtonInSd() < 0.1) {
      if (EstimateInputsNow(false, iteration)) continue;
      spdlog::debug("fit converged at the rounding floor (gain {:.3g}, undamped step {:.3g} sd)", search.gain,
                    step.NewtonInSd());
      Stop(TerminationType::kConvergence);
      break;
    }
    // Otherwise convergence is judged at the top of the next iteration, on its undamped step. An
    // estimated input moves the reversals, where the friction makes the sensitivities change
    // fastest: frozen only after input steps below a tenth of their sd too.
    reuse_sensitivities_ = search.taken.cwiseAbs().maxCoeff() < kFrozenSensitivityStep &&
                           search.lambda * step.nuisance_step_in_sd < kFrozenInputStep;
  }
  out_.iterations = iteration;
  return std::move(out_);
}

}  // namespace

MinimizerSummary Minimize(FitProblem& problem, const ScaledParameters& parameters, const ScaledPriors& priors,
                          const ScaledBounds& bounds, const EstimatorOptions& options, std::vector<double> theta,
                          const std::function<void(const FitProgress&)>& progress) {
  return GaussNewton(problem, parameters, priors, bounds, options, std::move(theta), progress).Run();
}

}  // namespace strut::ident::internal
