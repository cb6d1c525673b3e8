#include "strut/ident/cyclic_banded.h"

#include <algorithm>
#include <cassert>
#include <cmath>

extern "C" {
void dgbtrf_(const int* m, const int* n, const int* kl, const int* ku, double* ab, const int* ldab, int* ipiv,
             int* info);
void dgbtrs_(const char* trans, const int* n, const int* kl, const int* ku, const int* nrhs, const double* ab,
             const int* ldab, const int* ipiv, double* b, const int* ldb, int* info, std::size_t trans_len);
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

bool CyclicBandedLU::FactorizeDense(const CyclicBlockBanded& a) {
  dense_ = true;
  dense_lu_.compute(a.ToDense());
  const Eigen::MatrixXd& lu = dense_lu_.matrixLU();
  const double max_pivot = lu.diagonal().cwiseAbs().maxCoeff();
  const double min_pivot = lu.diagonal().cwiseAbs().minCoeff();
  border_rcond_ = max_pivot > 0 ? min_pivot / max_pivot : 0.0;
  ok_ = lu.allFinite() && border_rcond_ > 1e-15;
  return ok_;
}

namespace {

// In-place LU with partial pivoting of a small column-major m x m block; false if singular.
bool SmallLuFactor(double* a, int m, int* pivots) {
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
void SmallLuSolve(const double* lu, const int* pivots, int m, double* b, int cols, int ld) {
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

}  // namespace

bool CyclicBandedLU::Factorize(const CyclicBlockBanded& a) {
  n_ = a.points();
  m_ = a.block_size();
  lower_ = -a.kmin();
  upper_ = a.kmax();
  border_ = std::max({lower_, upper_, 1});
  ok_ = false;
  if (n_ < 2 * border_ + 2) return FactorizeDense(a);
  dense_ = false;

  const int ni = n_ - border_;  // interior points
  interior_rows_ = ni * m_;
  const int nb = border_ * m_;
  Eigen::MatrixXd interior_border = Eigen::MatrixXd::Zero(interior_rows_, nb);
  border_interior_.setZero(nb, interior_rows_);
  Eigen::MatrixXd border_border = Eigen::MatrixXd::Zero(nb, nb);

  // Split the couplings into interior-interior (handled by FactorizeInterior) and the rest.
  for (int mu = 0; mu < n_; ++mu) {
    for (int k = a.kmin(); k <= a.kmax(); ++k) {
      const int nu = ((mu + k) % n_ + n_) % n_;
      const bool row_interior = mu < ni, col_interior = nu < ni;
      if (row_interior && col_interior) continue;
      const auto blk = a.block(mu, k);
      for (int c = 0; c < m_; ++c)
        for (int r = 0; r < m_; ++r) {
          const double v = blk(r, c);
          const int i = mu * m_ + r, j = nu * m_ + c;
          if (row_interior) {
            interior_border(i, j - interior_rows_) += v;
          } else if (col_interior) {
            border_interior_(i - interior_rows_, j) += v;
          } else {
            border_border(i - interior_rows_, j - interior_rows_) += v;
          }
        }
    }
  }
  // Algebraic unknowns (no time derivative) never couple across the wrap-around: skip their columns.
  border_columns_.clear();
  for (int j = 0; j < nb; ++j)
    if (interior_border.col(j).cwiseAbs().maxCoeff() > 0.0) border_columns_.push_back(j);
  interior_border_.resize(interior_rows_, static_cast<int>(border_columns_.size()));
  for (std::size_t c = 0; c < border_columns_.size(); ++c) interior_border_.col(c) = interior_border.col(border_columns_[c]);

  if (!FactorizeInterior(a)) return FactorizeDense(a);  // interior singular although the whole may not be
  SolveInterior(interior_border_);                    // now A_II^-1 A_IB
  const Eigen::MatrixXd coupling = BorderTimes(interior_border_);
  Eigen::MatrixXd schur = border_border;
  for (std::size_t c = 0; c < border_columns_.size(); ++c) schur.col(border_columns_[c]) -= coupling.col(c);
  schur_.compute(schur);
  const Eigen::MatrixXd& lu = schur_.matrixLU();
  const double max_pivot = lu.diagonal().cwiseAbs().maxCoeff();
  const double min_pivot = lu.diagonal().cwiseAbs().minCoeff();
  border_rcond_ = max_pivot > 0 ? min_pivot / max_pivot : 0.0;
  ok_ = schur.allFinite() && interior_border_.allFinite() && border_rcond_ > 1e-15;
  return ok_;
}

bool CyclicBandedLU::FactorizeInterior(const CyclicBlockBanded& a) {
  const int ni = n_ - border_;
  lower_triangular_ = upper_ == 0;
  if (lower_triangular_) {
    const std::size_t mm = static_cast<std::size_t>(m_) * m_;
    band_.resize(ni * mm);
    sub_.resize(ni * lower_ * mm);
    pivots_.resize(interior_rows_);
    for (int mu = 0; mu < ni; ++mu) {
      const auto diag = a.block(mu, 0);
      std::copy(diag.data(), diag.data() + mm, band_.data() + mu * mm);
      if (!SmallLuFactor(band_.data() + mu * mm, m_, pivots_.data() + mu * m_)) return false;
      for (int k = -lower_; k < 0; ++k) {
        const auto blk = a.block(mu, k);
        std::copy(blk.data(), blk.data() + mm, sub_.data() + (static_cast<std::size_t>(mu) * lower_ + (k + lower_)) * mm);
      }
    }
    return true;
  }
  kl_ = lower_ * m_ + m_ - 1;
  ku_ = upper_ * m_ + m_ - 1;
  const int ldab = 2 * kl_ + ku_ + 1;
  band_.assign(static_cast<std::size_t>(ldab) * interior_rows_, 0.0);
  pivots_.resize(interior_rows_);
  for (int mu = 0; mu < ni; ++mu)
    for (int k = a.kmin(); k <= a.kmax(); ++k) {
      const int nu = mu + k;
      if (nu < 0 || nu >= ni) continue;
      const auto blk = a.block(mu, k);
      for (int c = 0; c < m_; ++c)
        for (int r = 0; r < m_; ++r) {
          const int i = mu * m_ + r, j = nu * m_ + c;
          band_[static_cast<std::size_t>(kl_ + ku_ + i - j) + static_cast<std::size_t>(j) * ldab] += blk(r, c);
        }
    }
  int info = 0;
  dgbtrf_(&interior_rows_, &interior_rows_, &kl_, &ku_, band_.data(), &ldab, pivots_.data(), &info);
  return info == 0;
}

void CyclicBandedLU::SolveInterior(Eigen::Ref<Eigen::MatrixXd> b) const {
  const int cols = static_cast<int>(b.cols());
  if (lower_triangular_) {
    // Block forward substitution: y_mu = D_mu^-1 (b_mu - sum_k A(mu, k) y_{mu+k}).
    const int ni = n_ - border_;
    const std::size_t mm = static_cast<std::size_t>(m_) * m_;
    for (int mu = 0; mu < ni; ++mu) {
      const std::size_t ld = static_cast<std::size_t>(b.outerStride());
      for (int k = -lower_; k < 0; ++k) {
        if (mu + k < 0) continue;
        const double* blk = sub_.data() + (static_cast<std::size_t>(mu) * lower_ + (k + lower_)) * mm;
        for (int j = 0; j < cols; ++j) {
          double* y = b.data() + j * ld + mu * m_;
          const double* x = b.data() + j * ld + (mu + k) * m_;
          for (int c = 0; c < m_; ++c) {
            const double xc = x[c];
            if (xc == 0.0) continue;
            for (int r = 0; r < m_; ++r) y[r] -= blk[r + c * m_] * xc;
          }
        }
      }
      SmallLuSolve(band_.data() + mu * mm, pivots_.data() + mu * m_, m_, b.data() + mu * m_, cols,
                   static_cast<int>(b.outerStride()));
    }
    return;
  }
  const int ldab = 2 * kl_ + ku_ + 1;
  const int ldb = static_cast<int>(b.outerStride());
  int info = 0;
  const char trans = 'N';
  dgbtrs_(&trans, &interior_rows_, &kl_, &ku_, &cols, band_.data(), &ldab, pivots_.data(), b.data(), &ldb, &info, 1);
}

Eigen::MatrixXd CyclicBandedLU::BorderTimes(const Eigen::MatrixXd& x) const {
  // Border rows touch only the last `lower_` interior points and (wrapping) the first `upper_`.
  const int nb = border_ * m_;
  Eigen::MatrixXd y = Eigen::MatrixXd::Zero(nb, x.cols());
  const int tail = std::min(lower_ * m_, interior_rows_);
  if (tail > 0)
    y.noalias() += border_interior_.rightCols(tail) * x.bottomRows(tail);
  const int head = std::min(upper_ * m_, interior_rows_ - tail);
  if (head > 0) y.noalias() += border_interior_.leftCols(head) * x.topRows(head);
  return y;
}

void CyclicBandedLU::Solve(Eigen::Ref<Eigen::MatrixXd> b) const {
  assert(ok_);
  if (dense_) {
    b = dense_lu_.solve(b);
    return;
  }
  const int nb = border_ * m_;
  Eigen::MatrixXd w = b.topRows(interior_rows_);
  SolveInterior(w);
  const Eigen::MatrixXd yb = schur_.solve(b.bottomRows(nb) - BorderTimes(w));
  for (std::size_t c = 0; c < border_columns_.size(); ++c)
    w.noalias() -= interior_border_.col(c) * yb.row(border_columns_[c]);
  b.topRows(interior_rows_) = w;
  b.bottomRows(nb) = yb;
}

}  // namespace strut::ident
