// Linear systems with a cyclic block-banded matrix: the Newton Jacobian of a periodic time
// discretisation. Block row mu couples to block columns mu + k (mod n) for k in [kmin, kmax].
// Factorised in O(n) work and memory, two ways:
// - block lower-triangular bands (backward schemes, kmax = 0): block forward substitution with
//   LU-factorised diagonal blocks on the interior, and a small dense Schur complement on the last
//   -kmin block points for the wrap-around corners (only the columns that do wrap);
// - any other band (central schemes), or when the border system fails: the points are reordered
//   0, n-1, 1, n-2, ... so that the cyclic matrix becomes banded with about twice the bandwidth,
//   and LAPACK dgbtrf factorises it with partial pivoting. (A Schur border on central schemes is
//   unstable: the open interior operator has parasitic growing modes.)
// Before either, algebraic unknowns (in no off-diagonal block) and algebraic equations (no
// off-diagonal block) are eliminated point by point when they pair up: the bands then hold only
// the dynamic unknowns (under stroke input the gas temperature alone, where force and pressure
// made the blocks 3 x 3).
#pragma once

#include <Eigen/Dense>
#include <memory>
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

//! Partial-pivoting LU of a small dense matrix after row and column equilibration.
struct EquilibratedFactors {
  Eigen::PartialPivLU<Eigen::MatrixXd> lu;
  Eigen::VectorXd row_scale, column_scale;
  Eigen::MatrixXd Solve(const Eigen::MatrixXd& b) const;
  Eigen::MatrixXd SolveTransposed(const Eigen::MatrixXd& b) const;  //!< A^T X = B
};

//! LU factorisation of a CyclicBlockBanded matrix. Work and memory O(n m (kmax - kmin) ^ 2 m^2).
class CyclicBandedLU {
 public:
  //! Factorises; returns false when the matrix is (numerically) singular.
  bool Factorize(const CyclicBlockBanded& a);
  bool ok() const { return ok_; }
  int rows() const { return n_ * m_; }
  //! Solves A X = B in place (B: rows() x any number of columns).
  void Solve(Eigen::Ref<Eigen::MatrixXd> b) const;
  //! Solves A^T X = B in place with the same factors (adjoint problems: one solve per output
  //! functional instead of one per input direction).
  void SolveTransposed(Eigen::Ref<Eigen::MatrixXd> b) const;
  //! Smallest over largest pivot of the equilibrated border (or dense) LU: a singularity hint.
  double border_rcond() const { return border_rcond_; }

 private:
  void SetShape(const CyclicBlockBanded& a);
  //! Everything but the elimination: the border, folded or dense LU of `a` itself.
  bool FactorizeBands(const CyclicBlockBanded& a);
  bool FactorizeEliminated(const CyclicBlockBanded& a);
  void SolveEliminated(Eigen::Ref<Eigen::MatrixXd> b, bool transposed) const;
  bool FactorizeDense(const CyclicBlockBanded& a);
  bool FactorizeFolded(const CyclicBlockBanded& a);
  bool FactorizeBorder(const CyclicBlockBanded& a);
  bool FactorizeInterior(const CyclicBlockBanded& a);
  void SolveInterior(Eigen::Ref<Eigen::MatrixXd> b) const;
  void SolveInteriorTransposed(Eigen::Ref<Eigen::MatrixXd> b) const;
  //! A_BI x (x: the interior rows).
  Eigen::MatrixXd BorderTimes(const Eigen::Ref<const Eigen::MatrixXd>& x) const;
  //! x -= A_BI^T y.
  void SubtractBorderTransposedTimes(const Eigen::MatrixXd& y, Eigen::Ref<Eigen::MatrixXd> x) const;
  //! The folded banded LU's solve (dgbtrs's substitutions on all columns at once; `trans` 'N' or 'T').
  void SolveFolded(Eigen::Ref<Eigen::MatrixXd> b, char trans) const;

  int n_ = 0, m_ = 0, border_ = 0, interior_rows_ = 0, kl_ = 0, ku_ = 0, lower_ = 0, upper_ = 0;
  bool ok_ = false;
  bool dense_ = false;
  bool folded_ = false;
  std::vector<double> band_;   // folded: LAPACK band LU of the whole; border: inverses of the interior diagonal blocks
  std::vector<double> sub_;    // border: the interior blocks below the diagonal, row point major
  std::vector<int> position_;  // folded: row position of each point
  std::vector<int> pivots_;
  Eigen::MatrixXd interior_border_;  // A_II^-1 A_IB, only the columns in border_columns_
  std::vector<int> border_columns_;  // border unknowns that interior rows couple to (others: zero columns)
  std::vector<unsigned> coupled_;     // per offset -lower_ .. -1, bit c: unknown c appears in a block there
  Eigen::MatrixXd border_interior_;  // A_BI, its only nonzero columns: those of the last border_tail_ interior rows
  int border_tail_ = 0;
  EquilibratedFactors schur_;     // of the border Schur complement
  EquilibratedFactors dense_lu_;  // of the whole matrix (small n, spectral)
  // Point-by-point elimination: per point the diagonal block is [K0 B; C E] in the rows
  // (dynamic equations, algebraic equations) and columns (dynamic unknowns, algebraic unknowns);
  // `reduced_` factorises `reduced_matrix_`, the bands of S = K - B E^-1 C (unused when every
  // unknown is algebraic); both are kept for the next factorisation of the same shape.
  bool eliminated_ = false;
  std::vector<int> dynamic_equations_, algebraic_equations_, dynamic_unknowns_, algebraic_unknowns_;
  std::vector<double> e_inverse_;    // per point, a x a: E^-1
  std::vector<double> e_inverse_c_;  // per point, a x d: E^-1 C
  std::vector<double> b_block_;      // per point, d x a: B
  CyclicBlockBanded reduced_matrix_;
  std::unique_ptr<CyclicBandedLU> reduced_;
  double border_rcond_ = 1.0;
};

}  // namespace strut::ident
