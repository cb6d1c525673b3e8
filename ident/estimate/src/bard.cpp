#include "strut/ident/bard.h"

#include <algorithm>
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

double BardStep::NewtonInSd() const {
  return newton.size() == 0 ? 0.0 : (newton.array().abs() / sd.array()).maxCoeff();
}

void EliminateNuisance(const std::vector<NuisanceBlock>& nuisance, Eigen::MatrixXd& h, Eigen::VectorXd& g) {
  for (const NuisanceBlock& b : nuisance) {
    if (b.empty()) continue;
    const Eigen::LLT<Eigen::MatrixXd> a(b.information);  // positive definite: the prior's I is in it
    const Eigen::MatrixXd ct = a.solve(b.coupling.transpose());  // A^-1 C^T
    h.noalias() -= b.coupling * ct;
    g.noalias() -= ct.transpose() * b.gradient;
  }
}

namespace {

BardStep ParameterStep(const Eigen::MatrixXd& h, const Eigen::VectorXd& g, const Eigen::VectorXd& x,
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

}  // namespace

BardStep ComputeBardStep(const Eigen::MatrixXd& h, const Eigen::VectorXd& g, const Eigen::VectorXd& x,
                         const ScaledPriors& priors, const ScaledBounds& bounds, double damping_sd,
                         const std::vector<NuisanceBlock>& nuisance) {
  if (nuisance.empty()) return ParameterStep(h, g, x, priors, bounds, damping_sd);
  // The nuisance damped like the parameters: a prior of sd `damping_sd` (in their prior sd) reset to
  // the current iterate. Near a velocity reversal the friction makes the outputs far from linear in
  // the input's high harmonics (one prior sd of harmonic 49 at 2 Hz moves the velocity by three
  // widths of the friction's arctan), and undamped steps can land in a wrong reversal.
  std::vector<NuisanceBlock> blocks = nuisance;
  for (NuisanceBlock& b : blocks)
    if (!b.empty()) b.information.diagonal().array() += 1.0 / (damping_sd * damping_sd);
  Eigen::MatrixXd reduced = h;
  Eigen::VectorXd gradient = g;
  EliminateNuisance(blocks, reduced, gradient);
  BardStep result = ParameterStep(reduced, gradient, x, priors, bounds, damping_sd);
  // Back-substitution per block: A d_c = g_c - C^T d (d the parameter step as taken).
  result.nuisance_step.assign(nuisance.size(), Eigen::VectorXd());
  for (std::size_t a = 0; a < nuisance.size(); ++a) {
    const NuisanceBlock& b = blocks[a];
    if (b.empty()) continue;
    const Eigen::LLT<Eigen::MatrixXd> llt(b.information);
    Eigen::VectorXd& d = result.nuisance_step[a];
    d = llt.solve(b.gradient - b.coupling.transpose() * result.step);
    // Its sd given the parameters, without the damping (the convergence measure).
    const Eigen::VectorXd sd = Eigen::LLT<Eigen::MatrixXd>(nuisance[a].information)
                                   .solve(Eigen::MatrixXd::Identity(d.size(), d.size()))
                                   .diagonal()
                                   .cwiseMax(1e-300)
                                   .cwiseSqrt();
    result.nuisance_step_in_sd = std::max(result.nuisance_step_in_sd, (d.array().abs() / sd.array()).maxCoeff());
    result.finite = result.finite && d.allFinite();
  }
  return result;
}

Posterior PosteriorCovariance(const Eigen::MatrixXd& information, const Eigen::MatrixXd& input_noise,
                              const ScaledPriors& priors, const std::vector<NuisanceBlock>& nuisance) {
  const Eigen::Index l = information.rows();
  Posterior p;
  Eigen::MatrixXd h = information;
  if (priors.precision.size() == l) h.diagonal() += priors.precision;
  // The output noise alone (no input estimated, no sandwich): what input_noise_factor compares with.
  const Eigen::VectorXd output_only = h.completeOrthogonalDecomposition().pseudoInverse().diagonal();
  if (!nuisance.empty()) {
    Eigen::VectorXd unused = Eigen::VectorXd::Zero(l);
    EliminateNuisance(nuisance, h, unused);
    h = 0.5 * (h + h.transpose());
  }
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
  if (input_noise.rows() == l && l > 0 && input_noise.allFinite()) {
    // Errors in variables: the measured input's noise moves the estimate by H^-1 J^T W dy; its
    // covariance (the sandwich H^-1 N H^-1) adds to the output-noise part H^-1.
    const Eigen::MatrixXd extra = p.covariance * input_noise * p.covariance;
    p.covariance += extra;
  }
  p.input_noise_factor = Eigen::VectorXd::Ones(l);
  for (Eigen::Index a = 0; a < l; ++a)
    if (output_only[a] > 0) p.input_noise_factor[a] = std::sqrt(std::max(p.covariance(a, a), 0.0) / output_only[a]);
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
