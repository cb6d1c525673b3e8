// The O(n) cyclic block-banded LU against a dense LU of the same matrix.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
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

// Like a model under stroke input: some equations hold no rate (no off-diagonal block) and some
// unknowns appear in no rate, in different positions, with values of very different sizes.
CyclicBlockBanded AlgebraicMatrix(int n, int m, int kmin, int kmax, const std::vector<int>& algebraic_equations,
                                  const std::vector<int>& algebraic_unknowns, unsigned seed) {
  CyclicBlockBanded a = RandomMatrix(n, m, kmin, kmax, seed, false);
  const auto has = [](const std::vector<int>& v, int i) { return std::find(v.begin(), v.end(), i) != v.end(); };
  for (int mu = 0; mu < n; ++mu)
    for (int k = kmin; k <= kmax; ++k) {
      auto b = a.block(mu, k);
      for (int r = 0; r < m; ++r)
        for (int c = 0; c < m; ++c)
          if (k != 0 && (has(algebraic_equations, r) || has(algebraic_unknowns, c))) b(r, c) = 0.0;
      if (k == 0)
        for (int r = 0; r < m; ++r) b.row(r) *= std::pow(10.0, 3 * r - 3);  // N, Pa, W rows
    }
  return a;
}

// || R (A x - b) || / || R b || with R scaling every row of A to largest entry 1 (rows in N and Pa).
double EquilibratedResidual(const Eigen::MatrixXd& a, const Eigen::MatrixXd& x, const Eigen::MatrixXd& b) {
  const Eigen::VectorXd r = a.rowwise().lpNorm<Eigen::Infinity>().cwiseInverse();
  return (r.asDiagonal() * (a * x - b)).norm() / (r.asDiagonal() * b).norm();
}

TEST(CyclicBandedLU, EliminatesAlgebraicUnknownsLikeDenseLu) {
  struct Case {
    Shape shape;
    std::vector<int> equations, unknowns;
  };
  // Every shape the elimination unrolls (2 + 1 under stroke input, 1 + 2 under force input,
  // 1 + 1, 1 + 3) and the run-time sizes (2 + 2, all algebraic), on every band path after it
  // (border, folded, dense).
  for (const Case& c : {Case{{60, 3, -3, 0}, {0, 1}, {0, 1}}, Case{{60, 3, -2, 2}, {0, 2}, {1, 2}},
                        Case{{40, 4, -1, 1}, {3}, {0}}, Case{{50, 3, -3, 0}, {0, 1, 2}, {0, 1, 2}},
                        Case{{7, 3, -3, 0}, {1}, {2}}, Case{{80, 3, -3, 0}, {1}, {1}},
                        Case{{30, 2, -2, 2}, {0}, {1}}, Case{{40, 2, -3, 0}, {1}, {0}},
                        Case{{40, 4, -3, 0}, {0, 3}, {1, 2}}, Case{{36, 4, -1, 1}, {0, 3}, {1, 2}}}) {
    const Shape& s = c.shape;
    SCOPED_TRACE(testing::Message() << "n=" << s.n << " m=" << s.m << " k=" << s.kmin << ".." << s.kmax
                                    << " algebraic " << c.equations.size());
    const CyclicBlockBanded a = AlgebraicMatrix(s.n, s.m, s.kmin, s.kmax, c.equations, c.unknowns, 11u + s.n);
    CyclicBandedLU lu;
    ASSERT_TRUE(lu.Factorize(a));
    const Eigen::MatrixXd dense = a.ToDense();
    const Eigen::MatrixXd b = Eigen::MatrixXd::Random(a.rows(), 5);
    Eigen::MatrixXd x = b;
    lu.Solve(x);
    const Eigen::MatrixXd expected = dense.partialPivLu().solve(b);
    // Point-by-point elimination is not backward stable like a pivoted LU of the whole; on these
    // random blocks (not all well conditioned) it stays within 1e-10, far below Newton's tolerances.
    EXPECT_LT(EquilibratedResidual(dense, x, b), 1e-10);
    EXPECT_LT((x - expected).norm() / expected.norm(), 1e-10);
    Eigen::MatrixXd xt = b;
    lu.SolveTransposed(xt);
    const Eigen::MatrixXd expected_t = dense.transpose().partialPivLu().solve(b);
    EXPECT_LT(EquilibratedResidual(dense.transpose(), xt, b), 1e-10);
    EXPECT_LT((xt - expected_t).norm() / expected_t.norm(), 1e-10);
  }
}

// A factorisation reuses its storage (the reduced bands and their LU) when the next matrix has the
// same shape: one LU object refactorised with other values, other shapes, without algebraic
// unknowns and with them again must solve each matrix like a dense LU of it.
TEST(CyclicBandedLU, RefactorisesOneObjectWithNewValuesAndShapes) {
  struct Step {
    Shape shape;
    std::vector<int> equations, unknowns;
    unsigned seed;
  };
  CyclicBandedLU lu;
  for (const Step& step : {Step{{80, 3, -3, 0}, {1}, {1}, 1u}, Step{{80, 3, -3, 0}, {1}, {1}, 2u},
                           Step{{80, 3, -3, 0}, {}, {}, 3u}, Step{{80, 3, -3, 0}, {0, 1}, {0, 1}, 4u},
                           Step{{64, 3, -2, 2}, {0, 1}, {0, 1}, 5u}, Step{{80, 3, -3, 0}, {1}, {1}, 6u}}) {
    const Shape& s = step.shape;
    SCOPED_TRACE(testing::Message() << "n=" << s.n << " k=" << s.kmin << ".." << s.kmax << " algebraic "
                                    << step.equations.size() << " seed " << step.seed);
    const CyclicBlockBanded a = AlgebraicMatrix(s.n, s.m, s.kmin, s.kmax, step.equations, step.unknowns, step.seed);
    ASSERT_TRUE(lu.Factorize(a));
    const Eigen::MatrixXd dense = a.ToDense();
    const Eigen::MatrixXd b = Eigen::MatrixXd::Random(a.rows(), 2);
    Eigen::MatrixXd x = b;
    lu.Solve(x);
    EXPECT_LT(EquilibratedResidual(dense, x, b), 1e-10);
    Eigen::MatrixXd xt = b;
    lu.SolveTransposed(xt);
    EXPECT_LT(EquilibratedResidual(dense.transpose(), xt, b), 1e-10);
  }
}

TEST(CyclicBandedLU, AlgebraicBlockSingularAtOnePointIsStillSolvedOrRefused) {
  // E singular at one point: the elimination steps aside and the banded LU decides.
  CyclicBlockBanded a = AlgebraicMatrix(40, 3, -3, 0, {0}, {0}, 5u);
  a.block(17, 0)(0, 0) = 0.0;  // E = 0 there, but the point's block as a whole is regular
  CyclicBandedLU lu;
  ASSERT_TRUE(lu.Factorize(a));
  const Eigen::MatrixXd b = Eigen::MatrixXd::Random(a.rows(), 2);
  Eigen::MatrixXd x = b;
  lu.Solve(x);
  EXPECT_LT(EquilibratedResidual(a.ToDense(), x, b), 1e-13);
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
