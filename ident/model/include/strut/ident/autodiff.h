// Forward-mode automatic differentiation for the model equations.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <unsupported/Eigen/AutoDiff>

namespace strut::ident {

//! Most derivative directions one evaluation carries (state, rate and parameter directions).
inline constexpr int kMaxDerivatives = 64;

using DerivativeVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxDerivatives, 1>;

//! A value with its first derivatives in a runtime number of directions; stored inline (no heap).
//! Used for parameter sensitivities.
using Jet = Eigen::AutoDiffScalar<DerivativeVector>;

//! Directions of the fixed-size Jet used for Newton Jacobians: each unknown and the time derivatives
//! the equations use (stroke 3, temperature 2, pressure 1, ...).
inline constexpr int kStateDirections = 8;
//! Fixed-size Jet: the compiler unrolls its arithmetic, which the Jacobian assembly needs for speed.
using StateJet = Eigen::AutoDiffScalar<Eigen::Matrix<double, kStateDirections, 1>>;

//! A Jet with value `v` that is the `direction`-th of `count` independent variables.
inline Jet MakeVariable(double v, int count, int direction) {
  return Jet(v, count, direction);
}

//! A Jet with value `v` that depends on none of `count` variables. Every Jet in one evaluation
//! must carry the same number of directions: Eigen's AutoDiff does not pad an empty derivative
//! that meets an expression.
inline Jet MakeConstant(double v, int count) { return Jet(v, DerivativeVector::Zero(count)); }

//! a^b for positive a; for Jets also the derivative in b (Eigen's pow takes a constant exponent).
inline double Pow(double a, double b) { return std::pow(a, b); }
template <class D>
Eigen::AutoDiffScalar<D> Pow(const Eigen::AutoDiffScalar<D>& a, const Eigen::AutoDiffScalar<D>& b) {
  return Eigen::AutoDiffScalar<D>(exp(b * log(a)));
}
inline double Atan(double a) { return std::atan(a); }
template <class D>
Eigen::AutoDiffScalar<D> Atan(const Eigen::AutoDiffScalar<D>& a) {  // Eigen 3.4's AutoDiff has no atan
  return Eigen::AutoDiffScalar<D>(std::atan(a.value()), a.derivatives() / (1.0 + a.value() * a.value()));
}
inline double Abs(double a) { return std::abs(a); }
template <class D>
Eigen::AutoDiffScalar<D> Abs(const Eigen::AutoDiffScalar<D>& a) {
  return Eigen::AutoDiffScalar<D>(abs(a));
}

inline double Value(double v) { return v; }
template <class D>
double Value(const Eigen::AutoDiffScalar<D>& v) { return v.value(); }

}  // namespace strut::ident
