// The O(n) cyclic block-banded LU against a dense LU of the same matrix.
#include <gtest/gtest.h>

#include <random>

#include "strut/ident/cyclic_banded.h"

namespace strut::ident {
namespace {

CyclicBlockBanded RandomMatrix(int n, int m, int kmin, int kmax, unsigned seed, bool sparse_corner_columns) {
  CyclicBlockBanded a(n, m, kmin, kmax);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  for (int mu = 0; mu < n; ++mu)
    for (int k = kmin; k <= kmax; ++k) {
      auto b = a.block(mu, k);
      for (int r = 0; r < m; ++r)
        for (int c = 0; c < m; ++c) {
          // Like an algebraic unknown: column 0 couples only on the diagonal block.
          if (sparse_corner_columns && c == 0 && k != 0) continue;
          // Like a first-order unknown of backward2: absent from the farthest offset only.
          if (sparse_corner_columns && c == 1 && k == kmin && kmin < -1 && m > 1) continue;
          b(r, c) = uniform(rng);
        }
      if (k == 0) b += 4.0 * (kmax - kmin + 1) * Eigen::MatrixXd::Identity(m, m);
    }
  return a;
}

struct Shape {
  int n, m, kmin, kmax;
};

TEST(CyclicBandedLU, SolvesAndSolvesTransposedLikeDenseLuForEverySchemeShape) {
  // backward2 (-3..0), central2 (-1..1), central4 (-2..2), tiny n (dense fallback), m = 1..4.
  for (const Shape s : {Shape{50, 3, -3, 0}, Shape{64, 2, -1, 1}, Shape{40, 4, -2, 2}, Shape{9, 3, -3, 0},
                        Shape{200, 1, -3, 0}, Shape{30, 3, -2, 1}}) {
    for (bool sparse : {false, true}) {
      SCOPED_TRACE(testing::Message() << "n=" << s.n << " m=" << s.m << " k=" << s.kmin << ".." << s.kmax);
      const CyclicBlockBanded a = RandomMatrix(s.n, s.m, s.kmin, s.kmax, 7u + s.n, sparse);
      CyclicBandedLU lu;
      ASSERT_TRUE(lu.Factorize(a));
      Eigen::MatrixXd b = Eigen::MatrixXd::Random(a.rows(), 3);
      Eigen::MatrixXd x = b;
      lu.Solve(x);
      const Eigen::MatrixXd expected = a.ToDense().partialPivLu().solve(b);
      EXPECT_LT((x - expected).norm() / expected.norm(), 1e-11);
      EXPECT_LT((a.ToDense() * x - b).norm() / b.norm(), 1e-12);
      EXPECT_LT((a.Multiply(x.col(0)) - b.col(0)).norm() / b.col(0).norm(), 1e-12);
      // The adjoint solve with the same factors.
      Eigen::MatrixXd xt = b;
      lu.SolveTransposed(xt);
      const Eigen::MatrixXd expected_t = a.ToDense().transpose().partialPivLu().solve(b);
      EXPECT_LT((xt - expected_t).norm() / expected_t.norm(), 1e-11);
      EXPECT_LT((a.ToDense().transpose() * xt - b).norm() / b.norm(), 1e-12);
    }
  }
}

TEST(CyclicBandedLU, ReportsASingularMatrix) {
  CyclicBlockBanded a(20, 2, -1, 1);  // all zero
  CyclicBandedLU lu;
  EXPECT_FALSE(lu.Factorize(a));
  // A matrix singular through its wrap-around: rows sum to zero (discrete derivative of a constant).
  CyclicBlockBanded d(30, 1, -1, 1);
  for (int mu = 0; mu < 30; ++mu) {
    d.block(mu, -1)(0, 0) = -0.5;
    d.block(mu, 1)(0, 0) = 0.5;
  }
  EXPECT_FALSE(lu.Factorize(d));
}

}  // namespace
}  // namespace strut::ident
