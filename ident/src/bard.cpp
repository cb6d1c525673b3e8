#include "strut/ident/bard.h"

#include <cmath>

namespace strut::ident {

double ScaledPriors::LogDensity(const Eigen::VectorXd& x) const {
  if (precision.size() == 0) return 0.0;
  return -0.5 * (precision.array() * (x - mean).array().square()).sum();
}

Eigen::VectorXd ScaledBounds::Project(const Eigen::VectorXd& x) const {
  if (lower.size() == 0) return x;
  return x.cwiseMax(lower).cwiseMin(upper);
}

double BardStep::StepInSd() const { return step.size() == 0 ? 0.0 : (step.array().abs() / sd.array()).maxCoeff(); }

double BardStep::NewtonInSd() const {
  return newton.size() == 0 ? 0.0 : (newton.array().abs() / sd.array()).maxCoeff();
}

BardStep ComputeBardStep(const Eigen::MatrixXd& h, const Eigen::VectorXd& g, const Eigen::VectorXd& x,
                         const ScaledPriors& priors, const ScaledBounds& bounds, double damping_sd) {
  const Eigen::Index l = g.size();
  Eigen::MatrixXd posterior = h;
  Eigen::VectorXd gradient = g;
  if (priors.precision.size() == l) {
    posterior.diagonal() += priors.precision;
    gradient.array() -= priors.precision.array() * (x - priors.mean).array();
  }
  BardStep result;
  result.step = Eigen::VectorXd::Zero(l);
  result.sd = posterior.ldlt().solve(Eigen::MatrixXd::Identity(l, l)).diagonal().cwiseMax(0.0).cwiseSqrt();
  // Parameters held at a bound: those sitting on it whose free step would leave the box. The step
  // of the others is solved again without them (an active set; one pass settles the usual case).
  std::vector<bool> held(l, false);
  result.newton = Eigen::VectorXd::Zero(l);
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<Eigen::Index> free;
    for (Eigen::Index k = 0; k < l; ++k)
      if (!held[k]) free.push_back(k);
    Eigen::MatrixXd damped(free.size(), free.size());
    Eigen::VectorXd rhs(free.size());
    for (std::size_t a = 0; a < free.size(); ++a) {
      rhs[a] = gradient[free[a]];
      for (std::size_t b = 0; b < free.size(); ++b) damped(a, b) = posterior(free[a], free[b]);
      damped(a, a) += 1.0 / (damping_sd * damping_sd);
    }
    const Eigen::VectorXd step = damped.ldlt().solve(rhs);
    for (std::size_t a = 0; a < free.size(); ++a) damped(a, a) -= 1.0 / (damping_sd * damping_sd);
    const Eigen::VectorXd newton = damped.ldlt().solve(rhs);
    result.step.setZero();
    result.newton.setZero();
    for (std::size_t a = 0; a < free.size(); ++a) result.step[free[a]] = step[a], result.newton[free[a]] = newton[a];
    if (bounds.lower.size() != l) break;
    bool changed = false;
    for (Eigen::Index k = 0; k < l; ++k) {
      const bool at_lower = x[k] <= bounds.lower[k] && result.step[k] < 0;
      const bool at_upper = x[k] >= bounds.upper[k] && result.step[k] > 0;
      if (!held[k] && (at_lower || at_upper)) held[k] = changed = true;
    }
    if (!changed) break;
  }
  result.finite = result.step.allFinite() && result.newton.allFinite();
  // Held parameters do not count against convergence: their step is zero.
  return result;
}

Posterior PosteriorCovariance(const Eigen::MatrixXd& information, const Eigen::MatrixXd& input_noise,
                              const ScaledPriors& priors) {
  const Eigen::Index l = information.rows();
  Posterior p;
  Eigen::MatrixXd h = information;
  if (priors.precision.size() == l) h.diagonal() += priors.precision;
  // Near-null directions of the information normalised to a unit diagonal: collinearity among the
  // parameters, whatever their scales (a prior's small precision on its own is not one).
  const Eigen::VectorXd norm = h.diagonal().cwiseMax(1e-300).cwiseSqrt().cwiseInverse();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(norm.asDiagonal() * h * norm.asDiagonal());
  for (Eigen::Index k = 0; k < l; ++k) {
    if (eig.eigenvalues()[k] > 1e-10) continue;
    std::vector<int> members;
    for (Eigen::Index a = 0; a < l; ++a)
      if (std::abs(eig.eigenvectors()(a, k)) > 0.3) members.push_back(static_cast<int>(a));
    p.undetermined.push_back(members);
  }
  p.covariance = h.completeOrthogonalDecomposition().pseudoInverse();
  p.input_noise_factor = Eigen::VectorXd::Ones(l);
  if (input_noise.rows() == l && l > 0 && input_noise.allFinite()) {
    // Errors in variables: the measured input's noise moves the estimate by H^-1 J^T W dy; its
    // covariance (the sandwich H^-1 N H^-1) adds to the output-noise part H^-1.
    const Eigen::MatrixXd extra = p.covariance * input_noise * p.covariance;
    for (Eigen::Index a = 0; a < l; ++a)
      p.input_noise_factor[a] = std::sqrt(1.0 + extra(a, a) / std::max(p.covariance(a, a), 1e-300));
    p.covariance += extra;
  }
  return p;
}

Eigen::MatrixXd ExperimentSandwich(const Eigen::MatrixXd& covariance, const std::vector<Eigen::VectorXd>& gradients) {
  const Eigen::Index l = covariance.rows();
  Eigen::MatrixXd meat = Eigen::MatrixXd::Zero(l, l);
  int count = 0;
  for (const Eigen::VectorXd& g : gradients) {
    if (g.size() != l || g.isZero(0.0)) continue;
    meat.noalias() += g * g.transpose();
    ++count;
  }
  if (count < 2) return Eigen::MatrixXd::Zero(l, l);
  meat *= static_cast<double>(count) / (count - 1);
  return covariance * meat * covariance;
}

}  // namespace strut::ident
