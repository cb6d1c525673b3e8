#include "strut/ident/cyclic_banded.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <memory>
#include <utility>

extern "C" {
void dgbtrf_(const int* m, const int* n, const int* kl, const int* ku, double* ab, const int* ldab, int* ipiv,
             int* info);
}

namespace strut::ident {

CyclicBlockBanded::CyclicBlockBanded(int n, int m, int kmin, int kmax)
    : n_(n), m_(m), kmin_(kmin), kmax_(kmax),
      blocks_(static_cast<std::size_t>(n) * (kmax - kmin + 1) * m * m, 0.0) {
  assert(kmin <= 0 && kmax >= 0 && n > 0 && m > 0);
}

void CyclicBlockBanded::SetZero() { std::fill(blocks_.begin(), blocks_.end(), 0.0); }

Eigen::VectorXd CyclicBlockBanded::Multiply(const Eigen::VectorXd& x) const {
  Eigen::VectorXd y = Eigen::VectorXd::Zero(rows());
  for (int mu = 0; mu < n_; ++mu)
    for (int k = kmin_; k <= kmax_; ++k) {
      const int nu = ((mu + k) % n_ + n_) % n_;
      y.segment(mu * m_, m_) += block(mu, k) * x.segment(nu * m_, m_);
    }
  return y;
}

Eigen::MatrixXd CyclicBlockBanded::ToDense() const {
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(rows(), rows());
  for (int mu = 0; mu < n_; ++mu)
    for (int k = kmin_; k <= kmax_; ++k) {
      const int nu = ((mu + k) % n_ + n_) % n_;
      a.block(mu * m_, nu * m_, m_, m_) += block(mu, k);
    }
  return a;
}

// LU of the equilibrated matrix R A C (rows, then columns, scaled to max 1): the pivot ratio is
// then a singularity test that does not depend on the units of equations and unknowns (N, Pa, W
// rows; m, Pa, K columns).
static bool EquilibratedLu(const Eigen::MatrixXd& a, EquilibratedFactors& f, double& pivot_ratio) {
  if (!a.allFinite()) return false;
  f.row_scale = a.rowwise().lpNorm<Eigen::Infinity>();
  if ((f.row_scale.array() == 0.0).any()) return false;  // a zero row: singular
  f.row_scale = f.row_scale.cwiseInverse();
  const Eigen::MatrixXd ra = f.row_scale.asDiagonal() * a;
  f.column_scale = ra.colwise().lpNorm<Eigen::Infinity>().transpose();
  if ((f.column_scale.array() == 0.0).any()) return false;  // a zero column: singular
  f.column_scale = f.column_scale.cwiseInverse();
  f.lu.compute(ra * f.column_scale.asDiagonal());
  const auto pivots = f.lu.matrixLU().diagonal().cwiseAbs();
  pivot_ratio = pivots.maxCoeff() > 0 ? pivots.minCoeff() / pivots.maxCoeff() : 0.0;
  return f.lu.matrixLU().allFinite() && pivot_ratio > 1e-13;
}

Eigen::MatrixXd EquilibratedFactors::Solve(const Eigen::MatrixXd& b) const {
  return column_scale.asDiagonal() * lu.solve(row_scale.asDiagonal() * b);
}

Eigen::MatrixXd EquilibratedFactors::SolveTransposed(const Eigen::MatrixXd& b) const {
  // A = R^-1 (LU) C^-1, so A^-T = R (LU)^-T C.
  const Eigen::MatrixXd scaled = column_scale.asDiagonal() * b;
  Eigen::MatrixXd x(scaled.rows(), scaled.cols());
  lu._solve_impl_transposed<false>(scaled, x);  // Eigen 3.4's transpose().solve() does not compile for LU
  return row_scale.asDiagonal() * x;
}

bool CyclicBandedLU::FactorizeDense(const CyclicBlockBanded& a) {
  dense_ = true;
  ok_ = EquilibratedLu(a.ToDense(), dense_lu_, border_rcond_);
  return ok_;
}

namespace {

// Every value finite, in one vectorised pass (a sum of finite values overflows only at 1e308).
bool AllFinite(const Eigen::MatrixXd& x) { return std::isfinite(x.sum()); }

// In-place LU with partial pivoting of a small column-major m x m block; false if singular.
// M > 0 fixes the size at compile time (the loops unroll), M = 0 takes m at run time.
template <int M = 0>
bool SmallLuFactor(double* a, int m_runtime, int* pivots) {
  const int m = M > 0 ? M : m_runtime;
  for (int c = 0; c < m; ++c) {
    int p = c;
    for (int r = c + 1; r < m; ++r)
      if (std::abs(a[r + c * m]) > std::abs(a[p + c * m])) p = r;
    pivots[c] = p;
    if (a[p + c * m] == 0.0 || !std::isfinite(a[p + c * m])) return false;
    if (p != c)
      for (int k = 0; k < m; ++k) std::swap(a[c + k * m], a[p + k * m]);
    const double inv = 1.0 / a[c + c * m];
    for (int r = c + 1; r < m; ++r) {
      a[r + c * m] *= inv;
      const double l = a[r + c * m];
      for (int k = c + 1; k < m; ++k) a[r + k * m] -= l * a[c + k * m];
    }
  }
  return true;
}

// Solves with the factors of SmallLuFactor; b is m x cols, column-major with leading dim ld.
template <int M = 0>
void SmallLuSolve(const double* lu, const int* pivots, int m_runtime, double* b, int cols, int ld) {
  const int m = M > 0 ? M : m_runtime;
  for (int j = 0; j < cols; ++j) {
    double* x = b + static_cast<std::size_t>(j) * ld;
    for (int c = 0; c < m; ++c)
      if (pivots[c] != c) std::swap(x[c], x[pivots[c]]);
    for (int r = 1; r < m; ++r)
      for (int k = 0; k < r; ++k) x[r] -= lu[r + k * m] * x[k];
    for (int r = m - 1; r >= 0; --r) {
      for (int k = r + 1; k < m; ++k) x[r] -= lu[r + k * m] * x[k];
      x[r] /= lu[r + r * m];
    }
  }
}

// Block forward substitution y_mu = D_mu^-1 (b_mu - sum_k A(mu, k) y_{mu+k}) with the inverse
// diagonal blocks; M > 0 fixes the block size at compile time so the small loops unroll.
template <int M>
void ForwardSubstitute(int m_runtime, const double* inverse_diagonal, const double* sub, int lower, int points,
                       const unsigned* coupled, double* b, int cols, std::size_t ld) {
  // Points outer, right-hand sides inner: each block is loaded once for all columns. `coupled[k +
  // lower]`: bit c set when unknown c couples to the point k < 0 before (algebraic unknowns never,
  // first-order ones not at offsets where only the second-derivative stencil reaches).
  const int m = M > 0 ? M : m_runtime;
  const std::size_t mm = static_cast<std::size_t>(m) * m;
  double acc[16];
  for (int mu = 0; mu < points; ++mu) {
    const double* inverse = inverse_diagonal + mu * mm;
    for (int j = 0; j < cols; ++j) {
      double* column = b + j * ld;
      double* y = column + static_cast<std::size_t>(mu) * m;
      for (int r = 0; r < m; ++r) acc[r] = y[r];
      for (int k = std::max(-lower, -mu); k < 0; ++k) {
        const double* blk = sub + (static_cast<std::size_t>(mu) * lower + (k + lower)) * mm;
        const double* x = column + static_cast<std::size_t>(mu + k) * m;
        const unsigned mask = coupled[k + lower];
        for (int c = 0; c < m; ++c)
          if (mask & (1u << c))
            for (int r = 0; r < m; ++r) acc[r] -= blk[r + c * m] * x[c];
      }
      for (int r = 0; r < m; ++r) {
        double v = 0.0;
        for (int c = 0; c < m; ++c) v += inverse[r + c * m] * acc[c];
        y[r] = v;
      }
    }
  }
}

// The transpose of ForwardSubstitute: A_II^T is block upper triangular, so points run backwards,
// y_mu = D_mu^-T (b_mu - sum_k A(mu - k, k)^T y_{mu-k}) over the later points mu - k (k < 0).
template <int M>
void BackwardSubstituteTransposed(int m_runtime, const double* inverse_diagonal, const double* sub, int lower,
                                  int points, const unsigned* coupled, double* b, int cols, std::size_t ld) {
  const int m = M > 0 ? M : m_runtime;
  const std::size_t mm = static_cast<std::size_t>(m) * m;
  double acc[16];
  for (int mu = points - 1; mu >= 0; --mu) {
    const double* inverse = inverse_diagonal + mu * mm;
    for (int j = 0; j < cols; ++j) {
      double* column = b + j * ld;
      double* y = column + static_cast<std::size_t>(mu) * m;
      for (int r = 0; r < m; ++r) acc[r] = y[r];
      // Only the columns of `coupled` unknowns are nonzero in the blocks below the diagonal: their
      // transposes touch only those rows.
      for (int k = -1; k >= -lower && mu - k < points; --k) {
        const int later = mu - k;
        const double* blk = sub + (static_cast<std::size_t>(later) * lower + (k + lower)) * mm;
        const double* x = column + static_cast<std::size_t>(later) * m;
        const unsigned mask = coupled[k + lower];
        for (int c = 0; c < m; ++c)
          if (mask & (1u << c))
            for (int r = 0; r < m; ++r) acc[c] -= blk[r + c * m] * x[r];
      }
      for (int r = 0; r < m; ++r) {
        double v = 0.0;
        for (int c = 0; c < m; ++c) v += inverse[c + r * m] * acc[c];
        y[r] = v;
      }
    }
  }
}

// The inverse of every interior diagonal block and a copy of the blocks below it.
template <int M>
bool InvertDiagonal(const CyclicBlockBanded& a, int m_runtime, int points, int lower, double* inverses, double* sub,
                    int* pivots) {
  const int m = M > 0 ? M : m_runtime;
  const std::size_t mm = static_cast<std::size_t>(m) * m;
  double lu[256];  // m <= 16 on this path
  for (int mu = 0; mu < points; ++mu) {
    const auto diag = a.block(mu, 0);
    std::copy(diag.data(), diag.data() + mm, lu);
    if (!SmallLuFactor<M>(lu, m, pivots + mu * m)) return false;
    double* inverse = inverses + mu * mm;
    std::fill(inverse, inverse + mm, 0.0);
    for (int r = 0; r < m; ++r) inverse[r + r * m] = 1.0;
    SmallLuSolve<M>(lu, pivots + mu * m, m, inverse, m, m);
    for (int k = -lower; k < 0; ++k) {
      const auto blk = a.block(mu, k);
      std::copy(blk.data(), blk.data() + mm, sub + (static_cast<std::size_t>(mu) * lower + (k + lower)) * mm);
    }
  }
  return true;
}

// The point-by-point passes of CyclicBandedLU's elimination for na algebraic and nd dynamic
// unknowns; NA, ND > 0 fix them at compile time (the common shapes unroll), 0 reads na, nd.
struct EliminationLayout {
  int n, m, na, nd;
  const int *eq_a, *eq_d, *unk_a, *unk_d;
  const double *e_inverse, *e_inverse_c, *b_block;
};

// Pass<NA, ND>::Run(args...) with the shape's unrolled instance when there is one.
template <template <int, int> class Pass, class... Args>
auto WithShape(int na, int nd, Args&&... args) {
  if (na == 2 && nd == 1) return Pass<2, 1>::Run(std::forward<Args>(args)...);  // stroke input: force, pressure
  if (na == 1 && nd == 1) return Pass<1, 1>::Run(std::forward<Args>(args)...);
  if (na == 1 && nd == 2) return Pass<1, 2>::Run(std::forward<Args>(args)...);  // force input: pressure
  if (na == 1 && nd == 3) return Pass<1, 3>::Run(std::forward<Args>(args)...);
  return Pass<0, 0>::Run(std::forward<Args>(args)...);
}

// Where the elimination writes: per point E^-1, E^-1 C and B, and the reduced bands.
struct EliminationOutput {
  double *e_inverse, *e_inverse_c, *b_block;
  CyclicBlockBanded* reduced;
  double rcond;
};

// Per point, from the diagonal block [K0 B; C E]: E^-1 by a pivoted LU of the row-equilibrated E
// (so that the pivot ratio is a singularity test whatever the units), E^-1 C, B, and the reduced
// blocks (K restricted to the dynamic rows and columns, S = K0 - B E^-1 C on the diagonal).
// False when some E is (numerically) singular. Fixed-size loops: this runs at every point of
// every factorisation.
template <int NA, int ND>
struct EliminatePoints {
  static bool Run(const CyclicBlockBanded& a, const EliminationLayout& l, EliminationOutput& out) {
    const int na = NA > 0 ? NA : l.na, nd = ND > 0 ? ND : l.nd, m = l.m;
    double e[256], scale[16];
    int pivots[16];
    for (int mu = 0; mu < l.n; ++mu) {
      const double* diag = a.block(mu, 0).data();  // column-major m x m
      const auto at = [&](int r, int c) { return diag[r + c * m]; };
      for (int i = 0; i < na; ++i) {
        double largest = 0.0, sum = 0.0;
        for (int j = 0; j < na; ++j) {
          const double v = std::abs(at(l.eq_a[i], l.unk_a[j]));
          largest = std::max(largest, v);
          sum += v;
        }
        if (!(largest > 0.0) || !std::isfinite(sum)) return false;
        scale[i] = 1.0 / largest;
        for (int j = 0; j < na; ++j) e[i + j * na] = at(l.eq_a[i], l.unk_a[j]) * scale[i];
      }
      if (!SmallLuFactor<NA>(e, na, pivots)) return false;
      double smallest = INFINITY, largest = 0.0;
      for (int i = 0; i < na; ++i) {
        smallest = std::min(smallest, std::abs(e[i + i * na]));
        largest = std::max(largest, std::abs(e[i + i * na]));
      }
      const double ratio = smallest / largest;
      if (!(ratio > 1e-13)) return false;
      out.rcond = std::min(out.rcond, ratio);
      // E^-1 = (R E)^-1 R with R the row scales.
      double* inverse = out.e_inverse + static_cast<std::size_t>(mu) * na * na;
      for (int j = 0; j < na; ++j)
        for (int i = 0; i < na; ++i) inverse[i + j * na] = i == j ? 1.0 : 0.0;
      SmallLuSolve<NA>(e, pivots, na, inverse, na, na);
      for (int j = 0; j < na; ++j)
        for (int i = 0; i < na; ++i) inverse[i + j * na] *= scale[j];
      double* inverse_c = out.e_inverse_c + static_cast<std::size_t>(mu) * na * nd;
      for (int j = 0; j < nd; ++j)
        for (int i = 0; i < na; ++i) {
          double v = 0.0;
          for (int k = 0; k < na; ++k) v += inverse[i + k * na] * at(l.eq_a[k], l.unk_d[j]);
          inverse_c[i + j * na] = v;
        }
      double* b = out.b_block + static_cast<std::size_t>(mu) * nd * na;
      for (int j = 0; j < na; ++j)
        for (int i = 0; i < nd; ++i) b[i + j * nd] = at(l.eq_d[i], l.unk_a[j]);
      if (nd == 0) continue;
      for (int k = a.kmin(); k <= a.kmax(); ++k) {
        const double* from = a.block(mu, k).data();
        double* to = out.reduced->block(mu, k).data();
        for (int j = 0; j < nd; ++j)
          for (int i = 0; i < nd; ++i) to[i + j * nd] = from[l.eq_d[i] + l.unk_d[j] * m];
        if (k != 0) continue;
        for (int j = 0; j < nd; ++j)
          for (int i = 0; i < nd; ++i) {
            double v = 0.0;
            for (int q = 0; q < na; ++q) v += b[i + q * nd] * inverse_c[q + j * na];
            to[i + j * nd] -= v;
          }
      }
    }
    return true;
  }
};

}  // namespace

void CyclicBandedLU::SetShape(const CyclicBlockBanded& a) {
  n_ = a.points();
  m_ = a.block_size();
  lower_ = -a.kmin();
  upper_ = a.kmax();
  border_ = std::max({lower_, upper_, 1});
  ok_ = false;
  dense_ = folded_ = eliminated_ = false;
}

bool CyclicBandedLU::Factorize(const CyclicBlockBanded& a) {
  SetShape(a);
  if (FactorizeEliminated(a)) return true;
  return FactorizeBands(a);
}

bool CyclicBandedLU::FactorizeBands(const CyclicBlockBanded& a) {
  if (n_ < 2 * border_ + 2) return FactorizeDense(a);
  // Backward schemes: block forward substitution plus a small border system. Central schemes:
  // the open (non-periodic) interior has parasitic growing modes that wreck the border system, so
  // they (and any border failure) go to the folded banded LU, stable by partial pivoting.
  if (upper_ > 0 || m_ > 16 || !FactorizeBorder(a)) return FactorizeFolded(a);  // 16: ForwardSubstitute's buffer
  return true;
}

bool CyclicBandedLU::FactorizeEliminated(const CyclicBlockBanded& a) {
  if (m_ > 16) return false;  // EliminatePoints' buffers
  // Which equations and unknowns appear in an off-diagonal block (a rate) anywhere: entry e of
  // `rate` is set when it is nonzero in some off-diagonal block (a branch-free pass).
  const int mm = m_ * m_;
  unsigned char rate[256] = {};
  for (int mu = 0; mu < n_; ++mu)
    for (int k = a.kmin(); k <= a.kmax(); ++k) {
      if (k == 0) continue;
      const double* blk = a.block(mu, k).data();
      for (int e = 0; e < mm; ++e) rate[e] |= blk[e] != 0.0;
    }
  dynamic_equations_.clear();
  algebraic_equations_.clear();
  dynamic_unknowns_.clear();
  algebraic_unknowns_.clear();
  for (int i = 0; i < m_; ++i) {
    bool equation = false, unknown = false;
    for (int j = 0; j < m_; ++j) {
      equation = equation || rate[i + j * m_];
      unknown = unknown || rate[j + i * m_];
    }
    (equation ? dynamic_equations_ : algebraic_equations_).push_back(i);
    (unknown ? dynamic_unknowns_ : algebraic_unknowns_).push_back(i);
  }
  const int na = static_cast<int>(algebraic_unknowns_.size()), nd = m_ - na;
  if (na == 0 || static_cast<int>(algebraic_equations_.size()) != na) return false;
  e_inverse_.resize(static_cast<std::size_t>(n_) * na * na);
  e_inverse_c_.resize(static_cast<std::size_t>(n_) * na * nd);
  b_block_.resize(static_cast<std::size_t>(n_) * nd * na);
  // Every reduced block is written below: a matrix of the same shape is reused as it is.
  const int reduced_m = std::max(nd, 1);
  if (reduced_matrix_.points() != n_ || reduced_matrix_.block_size() != reduced_m ||
      reduced_matrix_.kmin() != a.kmin() || reduced_matrix_.kmax() != a.kmax())
    reduced_matrix_ = CyclicBlockBanded(n_, reduced_m, a.kmin(), a.kmax());
  const EliminationLayout l{n_, m_, na, nd,
                            algebraic_equations_.data(), dynamic_equations_.data(),
                            algebraic_unknowns_.data(), dynamic_unknowns_.data(),
                            nullptr, nullptr, nullptr};
  EliminationOutput out{e_inverse_.data(), e_inverse_c_.data(), b_block_.data(), &reduced_matrix_, 1.0};
  if (!WithShape<EliminatePoints>(na, nd, a, l, out)) return false;
  if (nd > 0) {
    // The reduced bands hold only dynamic equations and unknowns: nothing is left to eliminate.
    if (!reduced_) reduced_ = std::make_unique<CyclicBandedLU>();
    reduced_->SetShape(reduced_matrix_);
    if (!reduced_->FactorizeBands(reduced_matrix_)) return false;
    out.rcond = std::min(out.rcond, reduced_->border_rcond());
  }
  eliminated_ = ok_ = true;
  border_rcond_ = out.rcond;
  return true;
}

namespace {

template <int NA, int ND>
void EliminateForward(const EliminationLayout& l, double* column, double* reduced) {
  const int na = NA > 0 ? NA : l.na, nd = ND > 0 ? ND : l.nd;
  double y[16];
  for (int mu = 0; mu < l.n; ++mu) {
    double* point = column + static_cast<std::ptrdiff_t>(mu) * l.m;
    const double* e = l.e_inverse + static_cast<std::size_t>(mu) * na * na;
    const double* bb = l.b_block + static_cast<std::size_t>(mu) * nd * na;
    for (int i = 0; i < na; ++i) {
      double v = 0.0;
      for (int j = 0; j < na; ++j) v += e[i + j * na] * point[l.eq_a[j]];
      y[i] = v;
    }
    for (int i = 0; i < nd; ++i) {
      double v = point[l.eq_d[i]];
      for (int j = 0; j < na; ++j) v -= bb[i + j * nd] * y[j];
      reduced[static_cast<std::ptrdiff_t>(mu) * nd + i] = v;
    }
    for (int i = 0; i < na; ++i) point[l.unk_a[i]] = y[i];  // y_A, kept for the back pass
  }
}

template <int NA, int ND>
void EliminateBack(const EliminationLayout& l, double* column, const double* reduced) {
  const int na = NA > 0 ? NA : l.na, nd = ND > 0 ? ND : l.nd;
  for (int mu = 0; mu < l.n; ++mu) {
    double* point = column + static_cast<std::ptrdiff_t>(mu) * l.m;
    const double* x = reduced + static_cast<std::ptrdiff_t>(mu) * nd;
    const double* ec = l.e_inverse_c + static_cast<std::size_t>(mu) * na * nd;
    for (int i = 0; i < na; ++i) {
      double v = point[l.unk_a[i]];
      for (int j = 0; j < nd; ++j) v -= ec[i + j * na] * x[j];
      point[l.unk_a[i]] = v;
    }
    for (int i = 0; i < nd; ++i) point[l.unk_d[i]] = x[i];
  }
}

template <int NA, int ND>
void EliminateForwardTransposed(const EliminationLayout& l, const double* column, double* reduced) {
  const int na = NA > 0 ? NA : l.na, nd = ND > 0 ? ND : l.nd;
  for (int mu = 0; mu < l.n; ++mu) {
    const double* point = column + static_cast<std::ptrdiff_t>(mu) * l.m;
    const double* ec = l.e_inverse_c + static_cast<std::size_t>(mu) * na * nd;
    for (int i = 0; i < nd; ++i) {
      double v = point[l.unk_d[i]];
      for (int j = 0; j < na; ++j) v -= ec[j + i * na] * point[l.unk_a[j]];
      reduced[static_cast<std::ptrdiff_t>(mu) * nd + i] = v;
    }
  }
}

template <int NA, int ND>
void EliminateBackTransposed(const EliminationLayout& l, double* column, const double* reduced) {
  const int na = NA > 0 ? NA : l.na, nd = ND > 0 ? ND : l.nd;
  double rest[16], y[16];
  for (int mu = 0; mu < l.n; ++mu) {
    double* point = column + static_cast<std::ptrdiff_t>(mu) * l.m;
    const double* x = reduced + static_cast<std::ptrdiff_t>(mu) * nd;
    const double* e = l.e_inverse + static_cast<std::size_t>(mu) * na * na;
    const double* bb = l.b_block + static_cast<std::size_t>(mu) * nd * na;
    for (int j = 0; j < na; ++j) {
      double v = point[l.unk_a[j]];
      for (int k = 0; k < nd; ++k) v -= bb[k + j * nd] * x[k];
      rest[j] = v;
    }
    for (int i = 0; i < na; ++i) {
      double v = 0.0;
      for (int j = 0; j < na; ++j) v += e[j + i * na] * rest[j];
      y[i] = v;
    }
    for (int i = 0; i < na; ++i) point[l.eq_a[i]] = y[i];
    for (int i = 0; i < nd; ++i) point[l.eq_d[i]] = x[i];
  }
}

// One pass for every column, with the shape's unrolled instance when there is one.
template <template <int, int> class Pass, class Column, class Reduced>
void ForEachColumn(const EliminationLayout& l, Eigen::Index cols, Column column, Reduced reduced) {
  for (Eigen::Index c = 0; c < cols; ++c) WithShape<Pass>(l.na, l.nd, l, column(c), reduced(c));
}
template <int NA, int ND>
struct Forward {
  static void Run(const EliminationLayout& l, double* c, double* r) { EliminateForward<NA, ND>(l, c, r); }
};
template <int NA, int ND>
struct Back {
  static void Run(const EliminationLayout& l, double* c, const double* r) { EliminateBack<NA, ND>(l, c, r); }
};
template <int NA, int ND>
struct ForwardTransposed {
  static void Run(const EliminationLayout& l, const double* c, double* r) { EliminateForwardTransposed<NA, ND>(l, c, r); }
};
template <int NA, int ND>
struct BackTransposed {
  static void Run(const EliminationLayout& l, double* c, const double* r) { EliminateBackTransposed<NA, ND>(l, c, r); }
};

}  // namespace

void CyclicBandedLU::SolveEliminated(Eigen::Ref<Eigen::MatrixXd> b, bool transposed) const {
  // Column by column, point by point on the point's m contiguous values.
  const int na = static_cast<int>(algebraic_unknowns_.size()), nd = m_ - na;
  const EliminationLayout l{n_, m_, na, nd,
                            algebraic_equations_.data(), dynamic_equations_.data(),
                            algebraic_unknowns_.data(), dynamic_unknowns_.data(),
                            e_inverse_.data(), e_inverse_c_.data(), b_block_.data()};
  const Eigen::Index cols = b.cols();
  Eigen::MatrixXd dynamic(static_cast<Eigen::Index>(n_) * nd, cols);
  const auto column = [&](Eigen::Index c) { return b.col(c).data(); };
  const auto reduced = [&](Eigen::Index c) { return dynamic.col(c).data(); };
  if (!transposed) {
    // y_A = E^-1 b_A; S x_D = b_D - B y_A; x_A = y_A - E^-1 C x_D.
    ForEachColumn<Forward>(l, cols, column, reduced);
    if (nd > 0) reduced_->Solve(dynamic);
    ForEachColumn<Back>(l, cols, column, reduced);
    return;
  }
  // A^T x = b, b indexed by unknowns, x by equations: S^T x_D = b_D - (E^-1 C)^T b_A, then
  // x_A = E^-T (b_A - B^T x_D).
  ForEachColumn<ForwardTransposed>(l, cols, column, reduced);
  if (nd > 0) reduced_->SolveTransposed(dynamic);
  ForEachColumn<BackTransposed>(l, cols, column, reduced);
}

bool CyclicBandedLU::FactorizeFolded(const CyclicBlockBanded& a) {
  // Order the points 0, n-1, 1, n-2, ...: every cyclic coupling is then a short one.
  folded_ = true;
  position_.resize(n_);
  for (int mu = 0; mu < n_; ++mu) position_[mu] = mu < (n_ + 1) / 2 ? 2 * mu : 2 * (n_ - 1 - mu) + 1;
  int reach = 0;
  for (int mu = 0; mu < n_; ++mu)
    for (int k = a.kmin(); k <= a.kmax(); ++k)
      reach = std::max(reach, std::abs(position_[mu] - position_[((mu + k) % n_ + n_) % n_]));
  const int rows = n_ * m_;
  kl_ = ku_ = (reach + 1) * m_ - 1;
  const int ldab = 2 * kl_ + ku_ + 1;
  band_.assign(static_cast<std::size_t>(ldab) * rows, 0.0);
  pivots_.resize(rows);
  for (int mu = 0; mu < n_; ++mu)
    for (int k = a.kmin(); k <= a.kmax(); ++k) {
      const int nu = ((mu + k) % n_ + n_) % n_;
      const auto blk = a.block(mu, k);
      for (int c = 0; c < m_; ++c)
        for (int r = 0; r < m_; ++r) {
          const int i = position_[mu] * m_ + r, j = position_[nu] * m_ + c;
          band_[static_cast<std::size_t>(kl_ + ku_ + i - j) + static_cast<std::size_t>(j) * ldab] += blk(r, c);
        }
    }
  int info = 0;
  dgbtrf_(&rows, &rows, &kl_, &ku_, band_.data(), &ldab, pivots_.data(), &info);
  if (info != 0) return false;
  // Singularity hint: smallest over largest |U| diagonal (U's diagonal is row kl + ku of the band).
  double smallest = INFINITY, largest = 0.0;
  for (int j = 0; j < rows; ++j) {
    const double d = std::abs(band_[static_cast<std::size_t>(kl_ + ku_) + static_cast<std::size_t>(j) * ldab]);
    smallest = std::min(smallest, d);
    largest = std::max(largest, d);
  }
  border_rcond_ = largest > 0 ? smallest / largest : 0.0;
  ok_ = std::isfinite(largest) && smallest > 0.0;
  return ok_;
}

bool CyclicBandedLU::FactorizeBorder(const CyclicBlockBanded& a) {
  const int ni = n_ - border_;  // interior points
  interior_rows_ = ni * m_;
  const int nb = border_ * m_;
  // Only the first `lower_` interior points reach the border (across the wrap-around) and only the
  // last `lower_` are reached from it: A_IB and A_BI are kept as those row and column blocks.
  const int head = std::min(lower_ * m_, interior_rows_);
  border_tail_ = std::min(lower_ * m_, interior_rows_);
  Eigen::MatrixXd interior_border_head = Eigen::MatrixXd::Zero(head, nb);
  border_interior_.setZero(nb, border_tail_);
  Eigen::MatrixXd border_border = Eigen::MatrixXd::Zero(nb, nb);
  const int tail_start = interior_rows_ - border_tail_;
  const auto add = [&](int mu, int k) {
    const int nu = ((mu + k) % n_ + n_) % n_;
    const bool row_interior = mu < ni, col_interior = nu < ni;
    if (row_interior && col_interior) return;
    const auto blk = a.block(mu, k);
    for (int c = 0; c < m_; ++c)
      for (int r = 0; r < m_; ++r) {
        const double v = blk(r, c);
        const int i = mu * m_ + r, j = nu * m_ + c;
        if (row_interior) {
          interior_border_head(i, j - interior_rows_) += v;
        } else if (col_interior) {
          border_interior_(i - interior_rows_, j - tail_start) += v;
        } else {
          border_border(i - interior_rows_, j - interior_rows_) += v;
        }
      }
  };
  for (int mu = 0; mu < std::min(lower_, ni); ++mu)
    for (int k = a.kmin(); k < 0; ++k) add(mu, k);
  for (int mu = ni; mu < n_; ++mu)
    for (int k = a.kmin(); k <= a.kmax(); ++k) add(mu, k);
  // Algebraic unknowns (no time derivative) never couple across the wrap-around: skip their columns.
  border_columns_.clear();
  for (int j = 0; j < nb; ++j)
    if (head > 0 && interior_border_head.col(j).cwiseAbs().maxCoeff() > 0.0) border_columns_.push_back(j);
  interior_border_.setZero(interior_rows_, static_cast<int>(border_columns_.size()));
  for (std::size_t c = 0; c < border_columns_.size(); ++c)
    interior_border_.col(c).head(head) = interior_border_head.col(border_columns_[c]);

  if (!FactorizeInterior(a)) return false;  // interior singular although the whole may not be
  SolveInterior(interior_border_);                    // now A_II^-1 A_IB
  const Eigen::MatrixXd coupling = BorderTimes(interior_border_);
  Eigen::MatrixXd schur = border_border;
  for (std::size_t c = 0; c < border_columns_.size(); ++c) schur.col(border_columns_[c]) -= coupling.col(c);
  ok_ = AllFinite(interior_border_) && EquilibratedLu(schur, schur_, border_rcond_);
  return ok_;
}

bool CyclicBandedLU::FactorizeInterior(const CyclicBlockBanded& a) {
  const int ni = n_ - border_;
  if (upper_ != 0) return false;
  const std::size_t mm = static_cast<std::size_t>(m_) * m_;
  band_.resize(ni * mm);
  sub_.resize(ni * lower_ * mm);
  pivots_.resize(interior_rows_);
  // Per offset below the diagonal, the unknowns whose columns are nonzero in some block there.
  coupled_.assign(lower_, m_ > 32 ? ~0u : 0u);
  for (int mu = 0; mu < ni && m_ <= 32; ++mu)
    for (int k = -lower_; k < 0; ++k) {
      const double* blk = a.block(mu, k).data();
      unsigned& mask = coupled_[k + lower_];
      for (int c = 0; c < m_; ++c)
        for (int r = 0; r < m_; ++r)
          if (blk[r + c * m_] != 0.0) mask |= 1u << c;
    }
  switch (m_) {
    case 1: return InvertDiagonal<1>(a, m_, ni, lower_, band_.data(), sub_.data(), pivots_.data());
    case 2: return InvertDiagonal<2>(a, m_, ni, lower_, band_.data(), sub_.data(), pivots_.data());
    case 3: return InvertDiagonal<3>(a, m_, ni, lower_, band_.data(), sub_.data(), pivots_.data());
    case 4: return InvertDiagonal<4>(a, m_, ni, lower_, band_.data(), sub_.data(), pivots_.data());
    default: return InvertDiagonal<0>(a, m_, ni, lower_, band_.data(), sub_.data(), pivots_.data());
  }
}

void CyclicBandedLU::SolveInterior(Eigen::Ref<Eigen::MatrixXd> b) const {
  const int cols = static_cast<int>(b.cols());
  const int points = n_ - border_;
  const std::size_t ld = static_cast<std::size_t>(b.outerStride());
  switch (m_) {
    case 1: return ForwardSubstitute<1>(m_, band_.data(), sub_.data(), lower_, points, coupled_.data(), b.data(), cols, ld);
    case 2: return ForwardSubstitute<2>(m_, band_.data(), sub_.data(), lower_, points, coupled_.data(), b.data(), cols, ld);
    case 3: return ForwardSubstitute<3>(m_, band_.data(), sub_.data(), lower_, points, coupled_.data(), b.data(), cols, ld);
    case 4: return ForwardSubstitute<4>(m_, band_.data(), sub_.data(), lower_, points, coupled_.data(), b.data(), cols, ld);
    default: return ForwardSubstitute<0>(m_, band_.data(), sub_.data(), lower_, points, coupled_.data(), b.data(), cols, ld);
  }
}

void CyclicBandedLU::SolveInteriorTransposed(Eigen::Ref<Eigen::MatrixXd> b) const {
  const int cols = static_cast<int>(b.cols());
  const int points = n_ - border_;
  const std::size_t ld = static_cast<std::size_t>(b.outerStride());
  const double* inverses = band_.data();
  const double* sub = sub_.data();
  switch (m_) {
    case 1: return BackwardSubstituteTransposed<1>(m_, inverses, sub, lower_, points, coupled_.data(), b.data(), cols, ld);
    case 2: return BackwardSubstituteTransposed<2>(m_, inverses, sub, lower_, points, coupled_.data(), b.data(), cols, ld);
    case 3: return BackwardSubstituteTransposed<3>(m_, inverses, sub, lower_, points, coupled_.data(), b.data(), cols, ld);
    case 4: return BackwardSubstituteTransposed<4>(m_, inverses, sub, lower_, points, coupled_.data(), b.data(), cols, ld);
    default: return BackwardSubstituteTransposed<0>(m_, inverses, sub, lower_, points, coupled_.data(), b.data(), cols, ld);
  }
}

Eigen::MatrixXd CyclicBandedLU::BorderTimes(const Eigen::Ref<const Eigen::MatrixXd>& x) const {
  return border_interior_ * x.bottomRows(border_tail_);
}

void CyclicBandedLU::SubtractBorderTransposedTimes(const Eigen::MatrixXd& y, Eigen::Ref<Eigen::MatrixXd> x) const {
  x.bottomRows(border_tail_).noalias() -= border_interior_.transpose() * y;
}

namespace {

// dgbtrs's substitutions with the band LU of dgbtrf (kl, ku; row kd = kl + ku of the band holds
// U's diagonal) on every right-hand side at once: y is row-major, a row one contiguous vector of
// `cols` values. Cols > 0 fixes the column count at compile time: a Newton step's single column
// then runs plain scalar loops instead of a vector loop's set-up per band entry.
template <int Cols>
void FoldedSubstitutions(const double* band_lu, const int* pivots, int rows, int kl, int ku, double* y,
                         Eigen::Index cols_runtime, char trans) {
  const Eigen::Index cols = Cols > 0 ? Cols : cols_runtime;
  const int ldab = 2 * kl + ku + 1, kd = kl + ku;
  const auto row = [&](int i) { return y + static_cast<std::ptrdiff_t>(i) * cols; };
  const auto subtract = [&](int to, double factor, int from) {  // row `to` -= factor * row `from`
    if (factor == 0.0) return;  // U's fill-in room that pivoting left empty (most of it)
    double* a = row(to);
    const double* f = row(from);
    for (Eigen::Index q = 0; q < cols; ++q) a[q] -= factor * f[q];
  };
  const auto swap = [&](int i, int j) { std::swap_ranges(row(i), row(i) + cols, row(j)); };
  const auto divide = [&](int i, double d) {
    double* a = row(i);
    for (Eigen::Index q = 0; q < cols; ++q) a[q] /= d;
  };
  // U(i, j) at band row kd + i - j of column j; L's multipliers below the diagonal at rows kd + 1 ...
  const auto band = [&](int i, int j) { return band_lu[static_cast<std::size_t>(kd + i - j) + static_cast<std::size_t>(j) * ldab]; };
  if (trans == 'N') {
    for (int j = 0; j + 1 < rows; ++j) {  // L, with the row interchanges as they were made
      const int p = pivots[j] - 1;
      if (p != j) swap(j, p);
      const int below = std::min(kl, rows - 1 - j);
      for (int i = 1; i <= below; ++i) subtract(j + i, band(j + i, j), j);
    }
    for (int j = rows - 1; j >= 0; --j) {  // U
      divide(j, band(j, j));
      for (int i = std::max(0, j - kd); i < j; ++i) subtract(i, band(i, j), j);
    }
  } else {
    for (int j = 0; j < rows; ++j) {  // U^T
      for (int i = std::max(0, j - kd); i < j; ++i) subtract(j, band(i, j), i);
      divide(j, band(j, j));
    }
    for (int j = rows - 2; j >= 0; --j) {  // L^T, the interchanges undone in reverse
      const int below = std::min(kl, rows - 1 - j);
      for (int i = 1; i <= below; ++i) subtract(j, band(j + i, j), j + i);
      const int p = pivots[j] - 1;
      if (p != j) swap(j, p);
    }
  }
}

}  // namespace

void CyclicBandedLU::SolveFolded(Eigen::Ref<Eigen::MatrixXd> b, char trans) const {
  // The band holds P A P^T (P: the folding order), so A^T = P^T (P A P^T)^T P reuses the order.
  // The substitutions run on a row-major copy (the reference BLAS's dtbsv walks the band once per
  // column).
  const int rows = n_ * m_;
  const Eigen::Index cols = b.cols();
  using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  RowMajor rhs(rows, cols);
  for (int mu = 0; mu < n_; ++mu) rhs.middleRows(position_[mu] * m_, m_) = b.middleRows(mu * m_, m_);
  if (cols == 1)
    FoldedSubstitutions<1>(band_.data(), pivots_.data(), rows, kl_, ku_, rhs.data(), cols, trans);
  else
    FoldedSubstitutions<0>(band_.data(), pivots_.data(), rows, kl_, ku_, rhs.data(), cols, trans);
  for (int mu = 0; mu < n_; ++mu) b.middleRows(mu * m_, m_) = rhs.middleRows(position_[mu] * m_, m_);
}

void CyclicBandedLU::Solve(Eigen::Ref<Eigen::MatrixXd> b) const {
  assert(ok_);
  if (eliminated_) return SolveEliminated(b, false);
  if (dense_) {
    b = dense_lu_.Solve(b);  // evaluated into a temporary first: no aliasing
    return;
  }
  if (folded_) return SolveFolded(b, 'N');
  // [A_II A_IB; A_BI A_BB] by the Schur complement S = A_BB - A_BI A_II^-1 A_IB of the border.
  const int nb = border_ * m_;
  auto w = b.topRows(interior_rows_);
  SolveInterior(w);
  const Eigen::MatrixXd yb = schur_.Solve(b.bottomRows(nb) - BorderTimes(w));
  Eigen::MatrixXd coupled(static_cast<Eigen::Index>(border_columns_.size()), yb.cols());
  for (std::size_t c = 0; c < border_columns_.size(); ++c) coupled.row(c) = yb.row(border_columns_[c]);
  w.noalias() -= interior_border_ * coupled;
  b.bottomRows(nb) = yb;
}

void CyclicBandedLU::SolveTransposed(Eigen::Ref<Eigen::MatrixXd> b) const {
  assert(ok_);
  if (eliminated_) return SolveEliminated(b, true);
  if (dense_) {
    b = dense_lu_.SolveTransposed(b);
    return;
  }
  if (folded_) return SolveFolded(b, 'T');
  // A^T = [A_II^T A_BI^T; A_IB^T A_BB^T]: the border first, by S^T x_B = b_B - (A_II^-1 A_IB)^T b_I,
  // then x_I = A_II^-T (b_I - A_BI^T x_B).
  const int nb = border_ * m_;
  auto w = b.topRows(interior_rows_);
  Eigen::MatrixXd rhs = b.bottomRows(nb);
  const Eigen::MatrixXd projected = interior_border_.transpose() * w;  // rows: border_columns_
  for (std::size_t c = 0; c < border_columns_.size(); ++c) rhs.row(border_columns_[c]) -= projected.row(c);
  const Eigen::MatrixXd xb = schur_.SolveTransposed(rhs);
  SubtractBorderTransposedTimes(xb, w);
  SolveInteriorTransposed(w);
  b.bottomRows(nb) = xb;
}

}  // namespace strut::ident
