#include "strut/ident/cyclic_banded.h"

#include <algorithm>
#include <cassert>

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

bool CyclicBandedLU::Factorize(const CyclicBlockBanded& a) {
  n_ = a.points();
  m_ = a.block_size();
  const int lower = -a.kmin(), upper = a.kmax();
  border_ = std::max({lower, upper, 1});
  ok_ = false;
  if (n_ < 2 * border_ + 2) return FactorizeDense(a);
  dense_ = false;

  const int ni = n_ - border_;  // interior points
  interior_rows_ = ni * m_;
  const int nb = border_ * m_;
  kl_ = lower * m_ + m_ - 1;
  ku_ = upper * m_ + m_ - 1;
  const int ldab = 2 * kl_ + ku_ + 1;
  band_.assign(static_cast<std::size_t>(ldab) * interior_rows_, 0.0);
  pivots_.resize(interior_rows_);
  interior_border_.setZero(interior_rows_, nb);
  border_interior_.setZero(nb, interior_rows_);
  Eigen::MatrixXd border_border = Eigen::MatrixXd::Zero(nb, nb);

  for (int mu = 0; mu < n_; ++mu) {
    for (int k = a.kmin(); k <= a.kmax(); ++k) {
      const int nu = ((mu + k) % n_ + n_) % n_;
      const auto blk = a.block(mu, k);
      const bool row_interior = mu < ni, col_interior = nu < ni;
      for (int c = 0; c < m_; ++c)
        for (int r = 0; r < m_; ++r) {
          const double v = blk(r, c);
          if (v == 0.0) continue;
          const int i = mu * m_ + r, j = nu * m_ + c;
          if (row_interior && col_interior) {
            // Interior couplings never wrap: |i - j| stays inside the band.
            band_[static_cast<std::size_t>(kl_ + ku_ + i - j) + static_cast<std::size_t>(j) * ldab] += v;
          } else if (row_interior) {
            interior_border_(i, j - interior_rows_) += v;
          } else if (col_interior) {
            border_interior_(i - interior_rows_, j) += v;
          } else {
            border_border(i - interior_rows_, j - interior_rows_) += v;
          }
        }
    }
  }

  int info = 0;
  dgbtrf_(&interior_rows_, &interior_rows_, &kl_, &ku_, band_.data(), &ldab, pivots_.data(), &info);
  if (info != 0) return FactorizeDense(a);  // interior singular although the whole may not be
  const char trans = 'N';
  dgbtrs_(&trans, &interior_rows_, &kl_, &ku_, &nb, band_.data(), &ldab, pivots_.data(), interior_border_.data(),
          &interior_rows_, &info, 1);
  if (info != 0) return false;
  const Eigen::MatrixXd schur = border_border - border_interior_ * interior_border_;
  schur_.compute(schur);
  const Eigen::MatrixXd& lu = schur_.matrixLU();
  const double max_pivot = lu.diagonal().cwiseAbs().maxCoeff();
  const double min_pivot = lu.diagonal().cwiseAbs().minCoeff();
  border_rcond_ = max_pivot > 0 ? min_pivot / max_pivot : 0.0;
  ok_ = schur.allFinite() && border_rcond_ > 1e-15;
  return ok_;
}

void CyclicBandedLU::Solve(Eigen::Ref<Eigen::MatrixXd> b) const {
  assert(ok_);
  if (dense_) {
    b = dense_lu_.solve(b);
    return;
  }
  const int nrhs = static_cast<int>(b.cols());
  const int nb = border_ * m_;
  const int ldab = 2 * kl_ + ku_ + 1;
  Eigen::MatrixXd w = b.topRows(interior_rows_);
  int info = 0;
  const char trans = 'N';
  dgbtrs_(&trans, &interior_rows_, &kl_, &ku_, &nrhs, band_.data(), &ldab, pivots_.data(), w.data(), &interior_rows_,
          &info, 1);
  const Eigen::MatrixXd yb = schur_.solve(b.bottomRows(nb) - border_interior_ * w);
  b.topRows(interior_rows_) = w - interior_border_ * yb;
  b.bottomRows(nb) = yb;
}

}  // namespace strut::ident
