// The two pieces of the Bard estimator that need no experiments: the damped step of eq. 19 and the
// posterior covariance, each checked against a dense reference on small problems.
#include <gtest/gtest.h>

#include <random>

#include "strut/ident/bard.h"

namespace strut::ident {
namespace {

//! A linear least-squares problem J x = y with white noise: information, gradient at x.
struct Linear {
  Eigen::MatrixXd j;
  Eigen::VectorXd y;
  Eigen::MatrixXd Information() const { return j.transpose() * j; }
  Eigen::VectorXd Gradient(const Eigen::VectorXd& x) const { return j.transpose() * (y - j * x); }
};

Linear Problem(int rows, int columns, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> unit(0.0, 1.0);
  Linear p{Eigen::MatrixXd(rows, columns), Eigen::VectorXd(rows)};
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < columns; ++c) p.j(r, c) = unit(rng);
    p.y[r] = unit(rng);
  }
  return p;
}

TEST(BardStep, WithoutDampingItIsTheLeastSquaresSolution) {
  const Linear p = Problem(40, 3, 1);
  const Eigen::VectorXd x0 = Eigen::VectorXd::Zero(3);
  const BardStep step = ComputeBardStep(p.Information(), p.Gradient(x0), x0, {}, {}, 1e12);
  ASSERT_TRUE(step.finite);
  const Eigen::VectorXd reference = p.j.colPivHouseholderQr().solve(p.y);
  EXPECT_LT((step.step - reference).norm(), 1e-9 * reference.norm());
  // The sd are those of the information alone (the damping never enters them).
  const Eigen::VectorXd sd = p.Information().inverse().diagonal().cwiseSqrt();
  EXPECT_LT((step.sd - sd).norm(), 1e-12 * sd.norm());
}

TEST(BardStep, DampingShortensTheStepAndPriorsPullToTheirMean) {
  const Linear p = Problem(40, 3, 2);
  const Eigen::VectorXd x0 = Eigen::VectorXd::Zero(3);
  const BardStep free = ComputeBardStep(p.Information(), p.Gradient(x0), x0, {}, {}, 1e12);
  const BardStep damped = ComputeBardStep(p.Information(), p.Gradient(x0), x0, {}, {}, 0.01);
  EXPECT_LT(damped.step.norm(), 0.5 * free.step.norm());
  // A tight prior at 0.7 on the first parameter: its step goes there, whatever the data say.
  ScaledPriors prior{Eigen::Vector3d(1e12, 0, 0), Eigen::Vector3d(0.7, 0, 0)};
  const BardStep pulled = ComputeBardStep(p.Information(), p.Gradient(x0), x0, prior, {}, 1e12);
  EXPECT_NEAR(pulled.step[0], 0.7, 1e-6);
  EXPECT_LT(pulled.sd[0], 1e-5);
  EXPECT_NEAR(prior.LogDensity(Eigen::Vector3d(0.7, 5, 5)), 0.0, 1e-12);
}

TEST(BardStep, AParameterAtItsBoundIsHeldAndTheOthersSolvedWithoutIt) {
  const Linear p = Problem(40, 3, 3);
  const Eigen::VectorXd x0 = Eigen::VectorXd::Zero(3);
  const BardStep free = ComputeBardStep(p.Information(), p.Gradient(x0), x0, {}, {}, 1e12);
  // Put a bound on the side the free step goes, at the start: that parameter must stay.
  ScaledBounds bounds{Eigen::Vector3d::Constant(-INFINITY), Eigen::Vector3d::Constant(INFINITY)};
  if (free.step[1] > 0)
    bounds.upper[1] = 0.0;
  else
    bounds.lower[1] = 0.0;
  const BardStep held = ComputeBardStep(p.Information(), p.Gradient(x0), x0, {}, bounds, 1e12);
  EXPECT_EQ(held.step[1], 0.0);
  // The others: the least-squares solution with the held column removed.
  Eigen::MatrixXd reduced(40, 2);
  reduced << p.j.col(0), p.j.col(2);
  const Eigen::VectorXd reference = reduced.colPivHouseholderQr().solve(p.y);
  EXPECT_NEAR(held.step[0], reference[0], 1e-9);
  EXPECT_NEAR(held.step[2], reference[1], 1e-9);
  EXPECT_EQ(bounds.Project(Eigen::Vector3d(1, 2, 3))[1], free.step[1] > 0 ? 0.0 : 2.0);
}

TEST(PosteriorCovariance, AddsTheInputNoiseAsASandwichAndNamesCollinearParameters) {
  const Linear p = Problem(50, 3, 4);
  const Eigen::MatrixXd h = p.Information();
  const Eigen::MatrixXd n = 0.3 * h;  // an input noise proportional to the information
  const Posterior post = PosteriorCovariance(h, n, {});
  const Eigen::MatrixXd c = h.inverse();
  EXPECT_LT((post.covariance - (c + c * n * c)).norm(), 1e-12 * c.norm());
  for (int a = 0; a < 3; ++a) EXPECT_NEAR(post.input_noise_factor[a], std::sqrt(1.3), 1e-9);
  EXPECT_TRUE(post.undetermined.empty());
  // Two identical columns: one near-null direction made of both, whatever their scale.
  Linear q = p;
  q.j.col(2) = 1e6 * q.j.col(1);
  const Posterior collinear = PosteriorCovariance(q.Information(), {}, {});
  ASSERT_EQ(collinear.undetermined.size(), 1u);
  EXPECT_EQ(collinear.undetermined[0], (std::vector<int>{1, 2}));
}

TEST(ExperimentSandwich, AgreesWithTheCovarianceWhenTheModelIsRightAndGrowsWithSystematicResiduals) {
  // 200 "experiments" of a linear model with white noise: the sandwich over them estimates C.
  std::mt19937_64 rng(5);
  std::normal_distribution<double> unit(0.0, 1.0);
  const int experiments = 200, rows = 20;
  std::vector<Eigen::MatrixXd> js;
  Eigen::MatrixXd h = Eigen::MatrixXd::Zero(2, 2);
  for (int a = 0; a < experiments; ++a) {
    Eigen::MatrixXd j(rows, 2);
    for (int r = 0; r < rows; ++r) j(r, 0) = 1.0, j(r, 1) = unit(rng);
    h += j.transpose() * j;
    js.push_back(j);
  }
  const Eigen::MatrixXd c = h.inverse();
  const auto sandwich = [&](double bias) {
    std::vector<Eigen::VectorXd> g;
    for (const auto& j : js) {
      Eigen::VectorXd e(rows);
      const double offset = bias * unit(rng);  // a misfit common to the experiment's residuals
      for (int r = 0; r < rows; ++r) e[r] = unit(rng) + offset;
      g.push_back(j.transpose() * e);
    }
    return ExperimentSandwich(c, g);
  };
  const Eigen::MatrixXd right = sandwich(0.0);
  for (int a = 0; a < 2; ++a) EXPECT_NEAR(right(a, a) / c(a, a), 1.0, 0.25) << a;
  // A systematic residual per experiment inflates the intercept's variance by about 1 + rows bias^2.
  const Eigen::MatrixXd wrong = sandwich(1.0);
  EXPECT_GT(wrong(0, 0) / c(0, 0), 10.0);
  EXPECT_EQ(ExperimentSandwich(c, {Eigen::VectorXd::Ones(2)}).norm(), 0.0);  // one experiment: no estimate
}

}  // namespace
}  // namespace strut::ident
