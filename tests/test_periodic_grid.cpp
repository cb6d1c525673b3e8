// Non-equidistant grids: per-point difference weights, interpolation from any grid to the data
// phases, the thinned grid of a slow experiment, and the periodic solver and its sensitivities on
// such a grid against the equidistant solution and finite differences.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "strut/ident/experiment_data.h"
#include "strut/ident/periodic.h"

namespace strut::ident {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

// A smooth non-equidistant grid: phases tau(s) = s + 0.08 sin(2 pi s) / (2 pi) at s = mu / n
// (spacing varies by a factor 1.17 around the period).
std::vector<double> WarpedPhases(int n) {
  std::vector<double> phases(n);
  for (int mu = 0; mu < n; ++mu) {
    const double s = static_cast<double>(mu) / n;
    phases[mu] = s + 0.08 * std::sin(kTwoPi * s) / kTwoPi;
  }
  return phases;
}

// Largest error of the stencil's first and second derivative of sin(2 pi tau) at every point.
std::pair<double, double> DerivativeErrors(const Stencil& s, const std::vector<double>& phases) {
  const int n = static_cast<int>(phases.size());
  double e1 = 0.0, e2 = 0.0;
  for (int mu = 0; mu < n; ++mu) {
    double d1 = 0.0, d2 = 0.0;
    for (int k = s.kmin; k <= s.kmax; ++k) {
      const double x = std::sin(kTwoPi * phases[((mu + k) % n + n) % n]);
      d1 += s.First(mu, k) * x;
      d2 += s.Second(mu, k) * x;
    }
    e1 = std::max(e1, std::abs(d1 - kTwoPi * std::cos(kTwoPi * phases[mu])));
    e2 = std::max(e2, std::abs(d2 + kTwoPi * kTwoPi * std::sin(kTwoPi * phases[mu])));
  }
  return {e1, e2};
}

TEST(StencilOnPhases, EquidistantPhasesGiveTheEquidistantWeights) {
  for (Scheme scheme : {Scheme::kBackward2, Scheme::kCentral2, Scheme::kCentral4}) {
    SCOPED_TRACE(std::string(ToString(scheme)));
    const int n = 64;
    std::vector<double> phases(n);
    for (int mu = 0; mu < n; ++mu) phases[mu] = static_cast<double>(mu) / n;
    const Stencil uniform = Stencil::For(scheme, n), at = Stencil::For(scheme, phases);
    ASSERT_FALSE(at.equidistant());
    for (int mu : {0, 1, 31, 63})
      for (int k = uniform.kmin; k <= uniform.kmax; ++k) {
        EXPECT_NEAR(at.First(mu, k), uniform.First(mu, k), 1e-9 * n) << mu << " " << k;
        EXPECT_NEAR(at.Second(mu, k), uniform.Second(mu, k), 1e-9 * n * n) << mu << " " << k;
      }
  }
  EXPECT_THROW(Stencil::For(Scheme::kSpectral, WarpedPhases(32)), std::invalid_argument);
  EXPECT_THROW(Stencil::For(Scheme::kCentral4, std::vector<double>{0.0, 0.2, 0.1, 0.3, 0.4, 0.5, 0.6, 0.7}),
               std::invalid_argument);
}

TEST(StencilOnPhases, DerivativesConvergeAtTheSchemesOrderOnAWarpedGrid) {
  // Doubling n divides the error by 2^order (second derivative of central4: its 5 points give
  // order 3 off an equidistant grid).
  const struct {
    Scheme scheme;
    double first_order, second_order;
  } cases[] = {{Scheme::kBackward2, 2, 2}, {Scheme::kCentral2, 2, 1}, {Scheme::kCentral4, 4, 3}};
  for (const auto& c : cases) {
    SCOPED_TRACE(std::string(ToString(c.scheme)));
    const auto [a1, a2] = DerivativeErrors(Stencil::For(c.scheme, WarpedPhases(100)), WarpedPhases(100));
    const auto [b1, b2] = DerivativeErrors(Stencil::For(c.scheme, WarpedPhases(200)), WarpedPhases(200));
    EXPECT_GT(std::log2(a1 / b1), c.first_order - 0.3);
    EXPECT_GT(std::log2(a2 / b2), c.second_order - 0.3);
    EXPECT_LT(b1, 1e-2 * kTwoPi);
  }
}

TEST(PhaseInterpolation, ExactOnGridPointsAndFourthOrderBetween) {
  const std::vector<double> grid = WarpedPhases(50);
  Eigen::MatrixXd rows(1, 50);
  for (int mu = 0; mu < 50; ++mu) rows(0, mu) = std::sin(kTwoPi * grid[mu]);
  // On the grid points (and wrapped round the period) the interpolation is the value itself.
  const std::vector<double> on = {grid[0], grid[17], grid[49], grid[3] + 1.0};
  const Eigen::MatrixXd at = PhaseInterpolation::Cubic(grid, 50, on).Rows(rows);
  EXPECT_DOUBLE_EQ(at(0, 0), rows(0, 0));
  EXPECT_DOUBLE_EQ(at(0, 1), rows(0, 17));
  EXPECT_DOUBLE_EQ(at(0, 2), rows(0, 49));
  EXPECT_NEAR(at(0, 3), rows(0, 3), 1e-15);
  // Between them (before the first and after the last point too) to the cubic's accuracy.
  std::vector<double> between;
  for (int i = 0; i < 997; ++i) between.push_back((i + 0.5) / 997.0);
  const auto error = [&](int n) {
    const std::vector<double> g = WarpedPhases(n);
    Eigen::MatrixXd r(1, n);
    for (int mu = 0; mu < n; ++mu) r(0, mu) = std::sin(kTwoPi * g[mu]);
    const Eigen::MatrixXd y = PhaseInterpolation::Cubic(g, n, between).Rows(r);
    double e = 0.0;
    for (std::size_t i = 0; i < between.size(); ++i) e = std::max(e, std::abs(y(0, i) - std::sin(kTwoPi * between[i])));
    return e;
  };
  EXPECT_LT(error(50), 1e-4);
  EXPECT_GT(std::log2(error(50) / error(100)), 3.7);
  // A target a rounding short of a whole period is the first point's, on either kind of grid.
  const std::vector<double> last = {std::nextafter(1.0, 0.0)};
  EXPECT_NEAR(PhaseInterpolation::Cubic(grid, 50, last).Rows(rows)(0, 0), rows(0, 0), 1e-12);
  Eigen::MatrixXd equidistant(1, 50);
  for (int mu = 0; mu < 50; ++mu) equidistant(0, mu) = std::sin(kTwoPi * mu / 50.0);
  EXPECT_NEAR(PhaseInterpolation::Cubic({}, 50, last).Rows(equidistant)(0, 0), 0.0, 1e-12);
}

TEST(PhaseProducts, GiveTheProductsOverTheTargetsAtTheGridsSize) {
  const int n = 40;
  const std::vector<double> grid = WarpedPhases(n);
  std::vector<double> targets(grid);  // every grid point, and 333 phases between
  for (int i = 0; i < 333; ++i) targets.push_back((i + 0.37) / 333.0);
  std::sort(targets.begin(), targets.end());
  const PhaseInterpolation map = PhaseInterpolation::Cubic(grid, n, targets);
  const PhaseProducts products(map, n);
  const Eigen::MatrixXd g = Eigen::MatrixXd::Random(n, 5);
  const Eigen::VectorXd r = Eigen::VectorXd::Random(static_cast<Eigen::Index>(targets.size()));
  const Eigen::MatrixXd j = map.Rows(g.transpose()).transpose();  // J = P G, targets x 5
  const Eigen::MatrixXd c = products.Columns(g);
  ASSERT_EQ(c.rows(), n);
  EXPECT_LT((c.transpose() * c - j.transpose() * j).norm(), 1e-12 * (j.transpose() * j).norm());
  EXPECT_LT((c.transpose() * products.Vector(r) - j.transpose() * r).norm(), 1e-12 * j.norm() * r.norm());
  // P^T P g back on the grid.
  Eigen::VectorXd spread = Eigen::VectorXd::Zero(n);
  for (std::size_t i = 0; i < targets.size(); ++i)
    for (int k = 0; k < 4; ++k) spread[map.taps[i][k]] += map.weights[i][k] * j(static_cast<Eigen::Index>(i), 2);
  EXPECT_LT((products.GridWeights(c.col(2)) - spread).norm(), 1e-12 * spread.norm());
}

TEST(ThinnedSamplePhases, KeepsEverySampleAtTheReversalsAndAroundAKink) {
  const int count = 5000, points = 200;
  Eigen::VectorXd velocity(count), force(count);
  for (int i = 0; i < count; ++i) {
    velocity[i] = std::cos(kTwoPi * i / count);
    force[i] = 1e4 * std::sin(kTwoPi * i / count) + (i > 1234 ? 300.0 * (i - 1234) : 0.0) * (i < 1600);
  }
  const std::vector<double> plain = ThinnedSamplePhases(velocity, points, {});
  const std::vector<double> kinked = ThinnedSamplePhases(velocity, points, {{&force, 1.0}});
  const auto has = [](const std::vector<double>& phases, int i) {
    return std::binary_search(phases.begin(), phases.end(), static_cast<double>(i) / 5000);
  };
  // Every sample within 10 of the reversals at 1250 and 3750 (speed below 1.3 % of its peak).
  for (int reversal : {1250, 3750})
    for (int i = reversal - 10; i <= reversal + 10; ++i) EXPECT_TRUE(has(plain, i)) << i;
  // Elsewhere up to count / points = 25 apart, never more.
  EXPECT_LT(plain.size(), 600u);
  EXPECT_GT(plain.size(), 200u);
  for (std::size_t k = 0; k < plain.size(); ++k) {
    const double next = k + 1 < plain.size() ? plain[k + 1] : 1.0 + plain[0];
    EXPECT_LE(std::lround((next - plain[k]) * count), 25);
  }
  // The ramp's ends (kinks at 1234 and 1600, far above the noise) get every sample around them.
  for (int kink : {1234, 1600})
    for (int i = kink - 4; i <= kink + 4; ++i) EXPECT_TRUE(has(kinked, i)) << i;
  EXPECT_FALSE(has(plain, 1601) && has(plain, 1602) && has(plain, 1600));
  // Too few samples for thinning: all of them.
  EXPECT_EQ(ThinnedSamplePhases(velocity.head(300), points, {}).size(), 300u);
}

// Experiment a of the standard matrix (0.04 Hz, 133 +- 127 mm) at 200 Hz: 5000 samples a period.
PeriodicInput StrokeA(const std::vector<double>& phases) {
  PeriodicInput in;
  in.frequency = 0.04;
  in.phases = phases;
  for (double tau : phases) in.values.push_back(0.133 + 0.127 * std::sin(kTwoPi * tau));
  return in;
}

TEST(PeriodicSolver, OnTheThinnedGridOfASlowExperimentMatchesEverySample) {
  // The thinned grid's solution, interpolated to all 5000 sample phases, against the solution on
  // all of them (central4, the stroke-input default): the force within 0.5 N and the pressure within
  // 10 Pa, far under the noise of a three-period mean (about 13 N and 1.3 kPa on the simulated rig).
  const Model model = Model::Build("2dof", Causality::kStrokeInput);
  const auto theta = model.defaults().values();
  PeriodicSolverOptions options;
  options.scheme = Scheme::kCentral4;
  const int count = 5000;
  Eigen::VectorXd velocity(count);
  std::vector<double> samples(count);
  for (int i = 0; i < count; ++i) {
    samples[i] = static_cast<double>(i) / count;
    velocity[i] = std::cos(kTwoPi * samples[i]);
  }
  const std::vector<double> thinned = ThinnedSamplePhases(velocity, 200, {});
  ASSERT_LT(thinned.size(), 600u);
  PeriodicSolver solver(model, options);
  const PeriodicSolution coarse = solver.Solve(StrokeA(thinned), theta);
  PeriodicSolver full_solver(model, options);
  PeriodicInput all = StrokeA({});
  for (double tau : samples) all.values.push_back(0.133 + 0.127 * std::sin(kTwoPi * tau));
  const PeriodicSolution full = full_solver.Solve(all, theta);
  const Eigen::MatrixXd mapped = PhaseInterpolation::Cubic(thinned, static_cast<int>(thinned.size()), samples).Rows(coarse.outputs);
  for (const char* channel : {"force", "pressure"}) {
    const auto row = std::find(full.channels.begin(), full.channels.end(), channel) - full.channels.begin();
    const double worst = (mapped.row(row) - full.outputs.row(row)).cwiseAbs().maxCoeff();
    EXPECT_LT(worst, std::string(channel) == "force" ? 0.5 : 10.0) << channel;
  }
  // The solution's time axis is the grid's.
  EXPECT_NEAR(coarse.time()[5], thinned[5] / 0.04, 1e-12);
}

TEST(PeriodicSolver, SensitivitiesOnAThinnedGridMatchFiniteDifferences) {
  // Parameters, input directions and the adjoint on a non-equidistant grid (experiment c's 1000
  // samples thinned), as the equidistant tests check them.
  const Model model = Model::Build("2dof", Causality::kStrokeInput);
  const auto theta = model.defaults().values();
  const int count = 1000;
  Eigen::VectorXd velocity(count);
  for (int i = 0; i < count; ++i) velocity[i] = std::cos(kTwoPi * i / count);
  const std::vector<double> phases = ThinnedSamplePhases(velocity, 200, {});
  const int n = static_cast<int>(phases.size());
  ASSERT_LT(n, count);
  PeriodicInput input;
  input.frequency = 0.2;
  input.phases = phases;
  for (double tau : phases) input.values.push_back(0.179 + 0.075 * std::sin(kTwoPi * tau));
  PeriodicSolverOptions tight;
  tight.tolerance = 1e-2;
  tight.scheme = Scheme::kCentral4;
  PeriodicSolver solver(model, tight);
  const PeriodicSolution base = solver.Solve(input, theta);
  const auto close = [](const Eigen::VectorXd& numeric, const Eigen::VectorXd& exact) {
    return (numeric - exact).cwiseAbs().maxCoeff() <= 2e-4 * std::max(exact.cwiseAbs().maxCoeff(), 1e-30) + 1e-12;
  };
  std::vector<int> parameters;
  for (int i = 0; i < model.parameter_count(); ++i) parameters.push_back(i);
  const auto sens = solver.OutputSensitivities(base, theta, parameters);
  for (std::size_t k = 0; k < parameters.size(); ++k) {
    const int i = parameters[k];
    const double h = 1e-5 * std::max(std::abs(theta[i]), model.defaults().spec(i).typical_size());
    auto plus = theta, minus = theta;
    plus[i] += h;
    minus[i] -= h;
    PeriodicSolver fd(model, tight);
    const PeriodicSolution sp = fd.Solve(input, plus, &base), sm = fd.Solve(input, minus, &base);
    for (int c = 0; c < static_cast<int>(base.channels.size()); ++c)
      EXPECT_TRUE(close((sp.outputs.row(c) - sm.outputs.row(c)).transpose() / (2 * h), sens[c].col(k)))
          << base.channels[c] << " w.r.t. " << model.defaults().spec(i).key();
  }
  Eigen::MatrixXd directions(n, 2);
  for (int mu = 0; mu < n; ++mu) {
    directions(mu, 0) = std::cos(kTwoPi * phases[mu]);
    directions(mu, 1) = std::sin(kTwoPi * 7 * phases[mu]);
  }
  const auto input_sens = solver.InputSensitivities(base, theta, directions);
  const double h = 1e-6;  // m
  for (int k = 0; k < 2; ++k) {
    PeriodicInput plus = input, minus = input;
    for (int mu = 0; mu < n; ++mu) {
      plus.values[mu] += h * directions(mu, k);
      minus.values[mu] -= h * directions(mu, k);
    }
    const PeriodicSolution sp = solver.Solve(plus, theta, &base), sm = solver.Solve(minus, theta, &base);
    for (int c = 0; c < static_cast<int>(base.channels.size()); ++c)
      EXPECT_TRUE(close((sp.outputs.row(c) - sm.outputs.row(c)).transpose() / (2 * h), input_sens[c].col(k)))
          << base.channels[c] << " direction " << k;
  }
  // The adjoint agrees with the forward sensitivities: w^T (dy/du phi) = (d(w^T y)/du)^T phi.
  std::vector<Eigen::MatrixXd> weights(base.channels.size(), Eigen::MatrixXd::Zero(n, 1));
  double forward = 0.0, scale = 0.0;
  for (std::size_t c = 0; c < base.channels.size(); ++c) {
    const double size = std::max(base.outputs.row(static_cast<int>(c)).cwiseAbs().maxCoeff(), 1e-30);
    for (int mu = 0; mu < n; ++mu) weights[c](mu, 0) = std::cos(kTwoPi * (c + 2) * phases[mu]) / size;
    forward += weights[c].col(0).dot(input_sens[c].col(1));
    scale += weights[c].col(0).cwiseAbs().dot(input_sens[c].col(1).cwiseAbs());
  }
  const Eigen::MatrixXd gradient = solver.InputGradients(base, theta, weights);
  EXPECT_NEAR(gradient.col(0).dot(directions.col(1)), forward, 1e-9 * scale + 1e-15);
}

}  // namespace
}  // namespace strut::ident
