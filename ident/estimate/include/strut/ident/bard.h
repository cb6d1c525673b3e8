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

//! One experiment's nuisance parameters in eq. 19 (errors in variables: the measured input's
//! Fourier coefficients), in units of their prior sd around the measured values, so their prior is
//! N(0, I). With J_c = d yhat / d(nuisance) and J = d yhat / d(scaled parameters):
struct NuisanceBlock {
  Eigen::MatrixXd information;  //!< sum J_c^T W J_c + I (the prior's precision included)
  Eigen::MatrixXd coupling;     //!< sum J^T W J_c: a row per estimated parameter, a column per nuisance
  Eigen::VectorXd gradient;     //!< sum J_c^T W e - xi (the prior's pull included)
  bool empty() const { return information.size() == 0; }
};

//! The parameters' information and gradient with the nuisance parameters eliminated (Schur
//! complement per block): h - sum C A^-1 C^T and g - sum C A^-1 g_c. The inverse of the reduced
//! information is the parameters' marginal posterior covariance (the nuisance's uncertainty in it).
void EliminateNuisance(const std::vector<NuisanceBlock>& nuisance, Eigen::MatrixXd& h, Eigen::VectorXd& g);

struct BardStep {
  Eigen::VectorXd step;  //!< scaled
  Eigen::VectorXd sd;    //!< posterior sd of each parameter (information plus priors, no damping), scaled
  //! The undamped Gauss-Newton step (the same system without the damping prior), scaled: how far
  //! the optimum still is. A damped step can be tiny far from it, in a narrow valley.
  Eigen::VectorXd newton;
  bool finite = false;
  //! Per nuisance block, its step (back-substituted: A^-1 (g_c - C^T step)); empty blocks get none.
  std::vector<Eigen::VectorXd> nuisance_step;
  //! Largest |nuisance step| over its sd given the parameters (sqrt of diag A^-1); 0 without.
  double nuisance_step_in_sd = 0.0;
  //! Largest |newton| / sd: the distance to the optimum in posterior sd (the convergence measure).
  double NewtonInSd() const;
};

//! Eq. 19: the Gauss-Newton step for the information `h` and gradient `g` (J^T W J, J^T W e) with
//! the user's `priors` at `x` and the paper's prior reset to the current iterate, of sd
//! `damping_sd` in every scaled parameter (a Levenberg-Marquardt-like damping; it never enters the
//! reported uncertainty). Parameters at a bound whose step points out of the box are held there.
//! With `nuisance` blocks: the step of the reduced equations (EliminateNuisance), the nuisance steps
//! back-substituted; the damping acts on the parameters only (the nuisance's prior bounds them).
BardStep ComputeBardStep(const Eigen::MatrixXd& h, const Eigen::VectorXd& g, const Eigen::VectorXd& x,
                         const ScaledPriors& priors, const ScaledBounds& bounds, double damping_sd,
                         const std::vector<NuisanceBlock>& nuisance = {});

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
//! the priors' precision, the `nuisance` blocks (estimated inputs) eliminated from it. Pseudo-inverse
//! where H is singular. `input_noise_factor` compares with the output noise alone (H without the
//! elimination, no sandwich).
Posterior PosteriorCovariance(const Eigen::MatrixXd& information, const Eigen::MatrixXd& input_noise,
                              const ScaledPriors& priors, const std::vector<NuisanceBlock>& nuisance = {});

//! The covariance the experiments' disagreement implies (a cluster-robust sandwich over the
//! experiments): C M C with C the posterior covariance and M = A/(A-1) sum_a g_a g_a^T from each
//! experiment's gradient g_a = J_a^T W e_a at the optimum. When the model is right E[g_a g_a^T] is
//! experiment a's information and this is about C; when physics is missing the residuals are
//! systematic within each experiment, the experiments pull the parameters apart, and this grows
//! where the white-noise covariance C cannot. Zero with fewer than 2 experiments.
Eigen::MatrixXd ExperimentSandwich(const Eigen::MatrixXd& covariance, const std::vector<Eigen::VectorXd>& gradients);

}  // namespace strut::ident
