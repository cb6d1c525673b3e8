// The two pieces of the modified Bayesian (Bard) estimator that need no experiments: the damped
// step of eq. 19 and the posterior covariance at the end. They work in scaled parameters
// (theta_i / scale_i), on the sums FitProblem::Linearise returns.
#pragma once

#include <Eigen/Dense>
#include <string>
#include <vector>

namespace strut::ident {

//! Normal priors on some estimated parameters, in scaled units: precision 1 / sd^2 (0: no prior)
//! and mean, per estimated parameter.
struct ScaledPriors {
  Eigen::VectorXd precision, mean;
  //! -1/2 sum precision (x - mean)^2
  double LogDensity(const Eigen::VectorXd& x) const;
};

//! Box bounds on the scaled estimated parameters (infinite where none).
struct ScaledBounds {
  Eigen::VectorXd lower, upper;
  //! x clipped into the box.
  Eigen::VectorXd Project(const Eigen::VectorXd& x) const;
};

struct BardStep {
  Eigen::VectorXd step;  //!< scaled
  Eigen::VectorXd sd;    //!< posterior sd of each parameter (information plus priors, no damping), scaled
  //! The undamped Gauss-Newton step (the same system without the damping prior), scaled: how far
  //! the optimum still is. A damped step can be tiny far from it, in a narrow valley.
  Eigen::VectorXd newton;
  bool finite = false;
  //! Largest |step| / sd: the damped step in units of the posterior uncertainty.
  double StepInSd() const;
  //! Largest |newton| / sd: the distance to the optimum in posterior sd (the convergence measure).
  double NewtonInSd() const;
};

//! Eq. 19: the Gauss-Newton step for the information `h` and gradient `g` (J^T W J, J^T W e) with
//! the user's `priors` at `x` and the paper's prior reset to the current iterate, of sd
//! `damping_sd` in every scaled parameter (a Levenberg-Marquardt-like damping; it never enters the
//! reported uncertainty). Parameters at a bound whose step points out of the box are held there.
BardStep ComputeBardStep(const Eigen::MatrixXd& h, const Eigen::VectorXd& g, const Eigen::VectorXd& x,
                         const ScaledPriors& priors, const ScaledBounds& bounds, double damping_sd);

//! The uncertainty at the final iterate.
struct Posterior {
  Eigen::MatrixXd covariance;            //!< scaled
  Eigen::VectorXd input_noise_factor;    //!< sd with the input's noise over sd without (1: none)
  //! Near-null directions of the information normalised to a unit diagonal (eigenvalue below
  //! 1e-10: collinear parameters): per direction the estimated parameters (positions among the
  //! estimated) that make it up.
  std::vector<std::vector<int>> undetermined;
};

//! H^-1 + H^-1 N H^-1 (the measured inputs' noise N as a sandwich) with H the information plus
//! the priors' precision. Pseudo-inverse where H is singular.
Posterior PosteriorCovariance(const Eigen::MatrixXd& information, const Eigen::MatrixXd& input_noise,
                              const ScaledPriors& priors);

//! The covariance the experiments' disagreement implies (a cluster-robust sandwich over the
//! experiments): C M C with C the posterior covariance and M = A/(A-1) sum_a g_a g_a^T from each
//! experiment's gradient g_a = J_a^T W e_a at the optimum. When the model is right E[g_a g_a^T] is
//! experiment a's information and this is about C; when physics is missing the residuals are
//! systematic within each experiment, the experiments pull the parameters apart, and this grows
//! where the white-noise covariance C cannot. Zero with fewer than 2 experiments.
Eigen::MatrixXd ExperimentSandwich(const Eigen::MatrixXd& covariance, const std::vector<Eigen::VectorXd>& gradients);

}  // namespace strut::ident
