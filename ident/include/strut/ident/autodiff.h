// Forward-mode automatic differentiation for the model equations.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <unsupported/Eigen/AutoDiff>

namespace strut::ident {

//! Most derivative directions one evaluation carries (state, rate and parameter directions).
inline constexpr int kMaxDerivatives = 48;

using DerivativeVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxDerivatives, 1>;

//! A value with its first derivatives in a runtime number of directions; stored inline (no heap).
using Jet = Eigen::AutoDiffScalar<DerivativeVector>;

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
inline Jet Pow(const Jet& a, const Jet& b) { return exp(b * log(a)); }
inline double Atan(double a) { return std::atan(a); }
inline Jet Atan(const Jet& a) {  // Eigen 3.4's AutoDiff has no atan
  return Jet(std::atan(a.value()), a.derivatives() / (1.0 + a.value() * a.value()));
}
inline double Abs(double a) { return std::abs(a); }
inline Jet Abs(const Jet& a) { return abs(a); }

inline double Value(double v) { return v; }
inline double Value(const Jet& v) { return v.value(); }

}  // namespace strut::ident
