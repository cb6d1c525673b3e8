// Linear systems with a cyclic block-banded matrix: the Newton Jacobian of a periodic time
// discretisation. Block row mu couples to block columns mu + k (mod n) for k in [kmin, kmax].
// Factorised in O(n) work and memory: the interior (no wrap-around) is a plain banded matrix;
// the wrap-around corners are handled by a small dense Schur complement on the last
// max(-kmin, kmax) block points. A block lower-triangular interior (backward schemes, kmax = 0)
// is solved by block forward substitution with LU-factorised diagonal blocks; any other band by
// LAPACK dgbtrf with partial pivoting.
#pragma once

#include <Eigen/Dense>
#include <vector>

namespace strut::ident {

class CyclicBlockBanded {
 public:
  CyclicBlockBanded() = default;
  //! n block rows of m x m blocks with offsets kmin <= 0 <= kmax; all blocks zero.
  CyclicBlockBanded(int n, int m, int kmin, int kmax);

  int points() const { return n_; }
  int block_size() const { return m_; }
  int kmin() const { return kmin_; }
  int kmax() const { return kmax_; }
  int rows() const { return n_ * m_; }

  //! The block coupling row point mu to column point mu + k (mod n).
  Eigen::Map<Eigen::MatrixXd> block(int mu, int k) {
    return Eigen::Map<Eigen::MatrixXd>(blocks_.data() + BlockOffset(mu, k), m_, m_);
  }
  Eigen::Map<const Eigen::MatrixXd> block(int mu, int k) const {
    return Eigen::Map<const Eigen::MatrixXd>(blocks_.data() + BlockOffset(mu, k), m_, m_);
  }
  void SetZero();

  //! y = A x
  Eigen::VectorXd Multiply(const Eigen::VectorXd& x) const;
  //! The whole matrix, dense (tests and small problems only).
  Eigen::MatrixXd ToDense() const;

 private:
  std::size_t BlockOffset(int mu, int k) const {
    return (static_cast<std::size_t>(mu) * (kmax_ - kmin_ + 1) + (k - kmin_)) * m_ * m_;
  }
  int n_ = 0, m_ = 0, kmin_ = 0, kmax_ = 0;
  std::vector<double> blocks_;
};

//! LU factorisation of a CyclicBlockBanded matrix. Work and memory O(n m (kmax - kmin) ^ 2 m^2).
class CyclicBandedLU {
 public:
  //! Factorises; returns false when the matrix is (numerically) singular.
  bool Factorize(const CyclicBlockBanded& a);
  bool ok() const { return ok_; }
  //! Solves A X = B in place (B: rows() x any number of columns).
  void Solve(Eigen::Ref<Eigen::MatrixXd> b) const;
  //! Reciprocal condition estimate of the border Schur complement (cheap singularity hint).
  double border_rcond() const { return border_rcond_; }

 private:
  bool FactorizeDense(const CyclicBlockBanded& a);
  bool FactorizeInterior(const CyclicBlockBanded& a);
  void SolveInterior(Eigen::Ref<Eigen::MatrixXd> b) const;
  //! border_interior_ * x, using only its nonzero column ranges.
  Eigen::MatrixXd BorderTimes(const Eigen::MatrixXd& x) const;

  int n_ = 0, m_ = 0, border_ = 0, interior_rows_ = 0, kl_ = 0, ku_ = 0, lower_ = 0, upper_ = 0;
  bool ok_ = false;
  bool dense_ = false;
  bool lower_triangular_ = false;
  std::vector<double> band_;   // LAPACK band storage of the interior block, or the LU of its diagonal blocks
  std::vector<double> sub_;    // lower_triangular_: the blocks below the diagonal, row point major
  std::vector<int> pivots_;
  Eigen::MatrixXd interior_border_;  // A_II^-1 A_IB, only the columns in border_columns_
  std::vector<int> border_columns_;  // border unknowns that interior rows couple to (others: zero columns)
  Eigen::MatrixXd border_interior_;  // A_BI
  Eigen::PartialPivLU<Eigen::MatrixXd> schur_;
  Eigen::PartialPivLU<Eigen::MatrixXd> dense_lu_;
  double border_rcond_ = 1.0;
};

}  // namespace strut::ident
