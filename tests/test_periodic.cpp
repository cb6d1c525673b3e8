// The periodic equilibrium solver: consistency, convergence order, sensitivities, errors.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <span>
#include <utility>

#include "strut/ident/periodic.h"

namespace strut::ident {
namespace {

// Experiment h of the standard matrix: middle position, 0.5 Hz, 34 mm.
PeriodicInput StrokeH(int n) { return PeriodicInput::Sine(0.5, 0.133, 0.034, n); }

PeriodicInput ForceOf(const PeriodicSolution& s) {
  PeriodicInput in{s.frequency, {}};
  const Eigen::VectorXd f = s.channel("force");
  in.values.assign(f.data(), f.data() + f.size());
  return in;
}

// The input of the 2dof model with `causality` on n points: experiment h's stroke, or the force
// the stroke-driven solution at `theta` needs for that stroke.
PeriodicInput TwoDofInput(Causality causality, std::span<const double> theta, int n) {
  const PeriodicInput stroke = StrokeH(n);
  if (causality == Causality::kStrokeInput) return stroke;
  return ForceOf(PeriodicSolver(Model::Build("2dof", Causality::kStrokeInput)).Solve(stroke, theta));
}

// The solver for `scheme` converged to a tolerance of 1e-2 (of the unknowns' scales), far below the
// effect of a finite-difference step.
PeriodicSolver TightSolver(const Model& model, Scheme scheme) {
  PeriodicSolverOptions tight;
  tight.tolerance = 1e-2;
  tight.scheme = scheme;
  return PeriodicSolver(model, tight);
}

// Input directions on n points (columns): a mean shift, the first cosine, the sine of `harmonic`.
Eigen::MatrixXd InputDirections(int n, int harmonic) {
  Eigen::MatrixXd directions(n, 3);
  for (int mu = 0; mu < n; ++mu) {
    directions(mu, 0) = 1.0;
    directions(mu, 1) = std::cos(2 * std::numbers::pi * mu / n);
    directions(mu, 2) = std::sin(2 * std::numbers::pi * harmonic * mu / n);
  }
  return directions;
}

// The solutions for the input moved by +step and by -step (per point), warm-started at `base`.
std::pair<PeriodicSolution, PeriodicSolution> SolveMovedBothWays(PeriodicSolver& solver, const PeriodicInput& input,
                                                                 std::span<const double> theta,
                                                                 const PeriodicSolution& base,
                                                                 const Eigen::VectorXd& step) {
  PeriodicInput plus = input, minus = input;
  for (int mu = 0; mu < step.size(); ++mu) {
    plus.values[mu] += step(mu);
    minus.values[mu] -= step(mu);
  }
  PeriodicSolution up = solver.Solve(plus, theta, &base);
  PeriodicSolution down = solver.Solve(minus, theta, &base);
  return {std::move(up), std::move(down)};
}

TEST(PeriodicSolver, ForceDrivenRunReproducesTheStrokeDrivenSolution) {
  for (const char* composition : {"1dof", "2dof"}) {
    SCOPED_TRACE(composition);
    const Model stroke_model = Model::Build(composition, Causality::kStrokeInput);
    const std::vector<double> theta = stroke_model.defaults().values();
    PeriodicSolver stroke_solver(stroke_model);
    const PeriodicSolution by_stroke = stroke_solver.Solve(StrokeH(400), theta);
    PeriodicSolver force_solver(Model::Build(composition, Causality::kForceInput));
    const PeriodicSolution by_force = force_solver.Solve(ForceOf(by_stroke), theta);
    EXPECT_LT((by_force.channel("stroke") - by_stroke.channel("stroke")).cwiseAbs().maxCoeff(), 1e-9);
    EXPECT_LT((by_force.channel("pressure") - by_stroke.channel("pressure")).cwiseAbs().maxCoeff(), 1e-3);
  }
}

// Largest difference of each unknown between two solutions, in units of its Newton tolerance.
Eigen::VectorXd ErrorInScales(const Model& model, const PeriodicSolution& a, const PeriodicSolution& b) {
  Eigen::VectorXd e(model.unknown_count());
  for (int j = 0; j < model.unknown_count(); ++j)
    e[j] = (a.unknowns.row(j) - b.unknowns.row(j)).cwiseAbs().maxCoeff() / model.unknown_spec(j).scale;
  return e;
}

TEST(PeriodicSolver, NewtonStopsWithinItsToleranceFromEveryStart) {
  // Cold (coarse-grid start), warm with the carried factorisation (simplified Newton), warm from a
  // guess without one, and a start too far for the carried factorisation: each ends within the
  // unknowns' scales of a solve converged a hundred times tighter with a new Jacobian each step.
  for (Causality causality : {Causality::kForceInput, Causality::kStrokeInput}) {
    SCOPED_TRACE(std::string(ToString(causality)));
    const Model model = Model::Build("2dof", causality);
    auto theta = model.defaults().values();
    PeriodicInput input = StrokeH(800);
    if (causality == Causality::kForceInput) input = ForceOf(PeriodicSolver(Model::Build("2dof", Causality::kStrokeInput)).Solve(input, theta));
    PeriodicSolverOptions tight;
    tight.tolerance = 1e-2;
    tight.reuse_contraction = 0.0;
    tight.coarse_points = 0;
    PeriodicSolver reference(model, tight), solver(model);
    const PeriodicSolution cold = solver.Solve(input, theta);
    EXPECT_LE(ErrorInScales(model, cold, reference.Solve(input, theta)).maxCoeff(), 1.0);
    ASSERT_TRUE(cold.solver_state.jacobian);
    for (const double change : {1.01, 1.3}) {
      SCOPED_TRACE(change);
      auto changed = theta;
      for (const char* name : {"theta4", "theta6", "theta16"}) changed[model.defaults().position(name)] *= change;
      const PeriodicSolution truth = reference.Solve(input, changed);
      const PeriodicSolution warm = solver.Solve(input, changed, &cold);
      EXPECT_LE(ErrorInScales(model, warm, truth).maxCoeff(), 1.0);
      PeriodicSolution guess = cold;
      guess.solver_state.jacobian.reset();
      const PeriodicSolution from_guess = solver.Solve(input, changed, &guess);
      EXPECT_LE(ErrorInScales(model, from_guess, truth).maxCoeff(), 1.0);
      EXPECT_GE(from_guess.factorizations, 1);
      if (change < 1.1) EXPECT_EQ(warm.factorizations, 0);  // the carried factorisation was enough
    }
  }
}

TEST(PeriodicSolver, WarmStartWithSensitivitiesStartsAtTheTangentPrediction) {
  const Model model = Model::Build("2dof", Causality::kForceInput);
  auto theta = model.defaults().values();
  const PeriodicInput force = ForceOf(PeriodicSolver(Model::Build("2dof", Causality::kStrokeInput)).Solve(StrokeH(800), theta));
  PeriodicSolver solver(model);
  const PeriodicSolution base = solver.Solve(force, theta);
  const PeriodicSolution plain = base;  // unknowns and factorisation, no sensitivities
  const std::vector<int> estimated = {model.defaults().position("theta4"), model.defaults().position("theta6"),
                                      model.defaults().position("theta16")};
  solver.OutputSensitivities(base, theta, estimated);
  ASSERT_EQ(base.solver_state.unknown_sensitivities.cols(), 3);
  auto changed = theta;
  for (int i : estimated) changed[i] *= 1.01;
  const PeriodicSolution tangent = solver.Solve(force, changed, &base), chord = solver.Solve(force, changed, &plain);
  EXPECT_LT(tangent.newton_iterations, chord.newton_iterations);
  EXPECT_LE(ErrorInScales(model, tangent, chord).maxCoeff(), 2.0);
  // A parameter without a sensitivity changed too: no prediction, still the solution.
  changed[model.defaults().position("theta3")] *= 1.01;
  const PeriodicSolution other = solver.Solve(force, changed, &base);
  PeriodicSolverOptions tight;
  tight.tolerance = 1e-2;
  EXPECT_LE(ErrorInScales(model, other, PeriodicSolver(model, tight).Solve(force, changed)).maxCoeff(), 1.0);
}

TEST(PeriodicSolver, CoarseGridStartReachesTheSameSolution) {
  const Model model = Model::Build("2dof", Causality::kForceInput);
  const auto theta = model.defaults().values();
  struct Sine {
    const char* label;
    double frequency, static_position, amplitude;
  };
  // Experiments b, f and l of the standard matrix (method.md).
  for (const Sine e : {Sine{"b", 0.1, 0.133, 0.127}, Sine{"f", 2.0, 0.249, 0.010}, Sine{"l", 0.5, 0.039, 0.035}}) {
    SCOPED_TRACE(e.label);
    const PeriodicInput input =
        ForceOf(PeriodicSolver(Model::Build("2dof", Causality::kStrokeInput))
                    .Solve(PeriodicInput::Sine(e.frequency, e.static_position, e.amplitude, 800), theta));
    PeriodicSolverOptions direct;
    direct.coarse_points = 0;
    const PeriodicSolution a = PeriodicSolver(model).Solve(input, theta);
    const PeriodicSolution b = PeriodicSolver(model, direct).Solve(input, theta);
    EXPECT_LE(ErrorInScales(model, a, b).maxCoeff(), 2.0) << ErrorInScales(model, a, b).transpose();
    EXPECT_LE(a.factorizations, b.factorizations);  // the coarse grid takes the damped steps
  }
}

TEST(PeriodicSolver, SolutionSatisfiesTheDiscretisedEquations) {
  const Model model = Model::Build("2dof", Causality::kStrokeInput);
  PeriodicSolver solver(model);
  const auto theta = model.defaults().values();
  const PeriodicSolution s = solver.Solve(StrokeH(800), theta);
  EXPECT_LT(solver.Residual(s.unknowns, s.input, theta).cwiseAbs().maxCoeff(), 1e3);  // 1 mN, 1 Pa, 1 mW
  ASSERT_EQ(s.time().size(), 800u);
  EXPECT_DOUBLE_EQ(s.time()[0], 0.0);
  EXPECT_NEAR(s.time()[1], 1.0 / (800 * 0.5), 1e-15);
  // Physics sanity: the gas heats on compression and the cycle is around ambient.
  const Eigen::VectorXd T = s.channel("temperature");
  EXPECT_GT(T.maxCoeff(), 293.15);
  EXPECT_LT(T.minCoeff(), 293.15 + 30);
}

TEST(PeriodicSolver, WarmStartConvergesFasterToTheSameSolution) {
  const Model model = Model::Build("2dof", Causality::kForceInput);
  auto theta = model.defaults().values();
  PeriodicSolver stroke_solver(Model::Build("2dof", Causality::kStrokeInput));
  const PeriodicInput force = ForceOf(stroke_solver.Solve(StrokeH(800), theta));
  PeriodicSolver solver(model);
  const PeriodicSolution base = solver.Solve(force, theta);
  theta[model.defaults().position("theta4")] *= 1.01;
  const PeriodicSolution cold = solver.Solve(force, theta);
  const PeriodicSolution warm = solver.Solve(force, theta, &base);
  // The warm start reuses the base's factorisation: no Jacobian assembled at all.
  EXPECT_EQ(warm.factorizations, 0);
  EXPECT_GE(cold.factorizations, 1);
  EXPECT_LT((warm.unknowns - cold.unknowns).row(0).cwiseAbs().maxCoeff(), 1e-9);
}

// Max stroke error of a force-driven solution against a fine central4 reference.
double StrokeError(Scheme scheme, int n, const PeriodicInput& fine, const Eigen::VectorXd& reference, int fine_n) {
  PeriodicSolverOptions options;
  options.scheme = scheme;
  PeriodicSolver solver(Model::Build("2dof", Causality::kForceInput), options);
  PeriodicInput coarse{fine.frequency, {}};
  for (int mu = 0; mu < n; ++mu) coarse.values.push_back(fine.values[mu * (fine_n / n)]);
  const PeriodicSolution s = solver.Solve(coarse, Model::Build("2dof", Causality::kForceInput).defaults().values());
  const Eigen::VectorXd stroke = s.channel("stroke");
  double error = 0.0;
  for (int mu = 0; mu < n; ++mu) error = std::max(error, std::abs(stroke[mu] - reference[mu * (fine_n / n)]));
  return error;
}

TEST(PeriodicSolver, SchemesConvergeAtTheirOrder) {
  const int fine_n = 12800;
  const auto theta = Model::Build("2dof", Causality::kForceInput).defaults().values();
  PeriodicSolver stroke_solver(Model::Build("2dof", Causality::kStrokeInput));
  const PeriodicInput fine = ForceOf(stroke_solver.Solve(StrokeH(fine_n), theta));
  PeriodicSolverOptions options;
  options.scheme = Scheme::kCentral4;
  PeriodicSolver reference_solver(Model::Build("2dof", Causality::kForceInput), options);
  const Eigen::VectorXd reference = reference_solver.Solve(fine, theta).channel("stroke");
  const auto order = [&](Scheme scheme, int n) {
    return std::log2(StrokeError(scheme, n, fine, reference, fine_n) / StrokeError(scheme, 2 * n, fine, reference, fine_n));
  };
  EXPECT_NEAR(order(Scheme::kBackward2, 200), 2.0, 0.35);
  EXPECT_NEAR(order(Scheme::kCentral2, 200), 2.0, 0.35);
  EXPECT_NEAR(order(Scheme::kCentral4, 100), 4.0, 0.5);
  // Spectral: far beyond every difference scheme at a fraction of the points.
  const double spectral32 = StrokeError(Scheme::kSpectral, 32, fine, reference, fine_n);
  const double central4_100 = StrokeError(Scheme::kCentral4, 100, fine, reference, fine_n);
  EXPECT_LT(spectral32, 0.1 * central4_100);
}

TEST(PeriodicSolver, EverySchemeSolvesTheForceDrivenOneDof) {
  // Central schemes once failed here: a border Schur complement on the open central operator is
  // unstable (parasitic modes), so central bands use the folded banded LU.
  const Model model = Model::Build("1dof", Causality::kForceInput);
  const auto theta = model.defaults().values();
  for (Scheme scheme : {Scheme::kBackward2, Scheme::kCentral2, Scheme::kCentral4, Scheme::kSpectral}) {
    for (int n : {64, 400}) {
      SCOPED_TRACE(std::string(ToString(scheme)) + " n=" + std::to_string(n));
      PeriodicSolverOptions options;
      options.scheme = scheme;
      PeriodicSolver solver(model, options);
      const PeriodicSolution s = solver.Solve(PeriodicInput::Sine(0.5, 6000, 1500, n), theta);
      // 0.1 N, 1e-4 of the force amplitude: the stroke steps stop at 1e-9 m, which near the
      // friction switches (atan sharpness 2000 s/m) is worth tens of mN.
      EXPECT_LT(solver.Residual(s.unknowns, s.input, theta).cwiseAbs().maxCoeff(), 1e5);
    }
  }
}

// A tightly solved 2dof state that input derivatives are checked at: experiment h's input on n points.
struct InputDerivativeCase {
  Causality causality;
  std::span<const double> theta;
  int n;
  const PeriodicInput& input;
  PeriodicSolver& solver;
  const PeriodicSolution& base;
};

// Runs `check` under each causality with backward2 and with central4.
template <class Check>
void ForEachInputDerivativeCase(Check check) {
  for (Causality causality : {Causality::kForceInput, Causality::kStrokeInput}) {
    for (Scheme scheme : {Scheme::kBackward2, Scheme::kCentral4}) {
      SCOPED_TRACE(std::string(ToString(causality)) + " " + std::string(ToString(scheme)));
      const Model model = Model::Build("2dof", causality);
      const auto theta = model.defaults().values();
      const int n = 200;
      const PeriodicInput input = TwoDofInput(causality, theta, n);
      PeriodicSolver solver = TightSolver(model, scheme);
      const PeriodicSolution base = solver.Solve(input, theta);
      check(InputDerivativeCase{causality, theta, n, input, solver, base});
    }
  }
}

TEST(PeriodicSolver, InputGradientsMatchFiniteDifferencesOfTheSolver) {
  // The adjoint: d(w^T y)/du projected on input perturbations (a mean shift, harmonics) against
  // solves with the input perturbed both ways, for weights on every output at once. Every scheme:
  // the input's rates reach the residual through each one's stencil (transposed here).
  ForEachInputDerivativeCase([](const InputDerivativeCase& at) {
    const auto& [causality, theta, n, input, solver, base] = at;
    const Eigen::MatrixXd directions = InputDirections(n, 3);
    // Two functionals: smooth weights on every output, and a single point of the first one.
    const int channels = static_cast<int>(base.channels.size());
    std::vector<Eigen::MatrixXd> weights(channels, Eigen::MatrixXd::Zero(n, 2));
    for (int c = 0; c < channels; ++c) {
      const double size = std::max(base.outputs.row(c).cwiseAbs().maxCoeff(), 1e-30);
      for (int mu = 0; mu < n; ++mu) weights[c](mu, 0) = (1.0 + 0.5 * std::sin(2 * std::numbers::pi * (c + 1) * mu / n)) / size;
    }
    weights[0](37, 1) = 1.0;
    const Eigen::MatrixXd gradient = solver.InputGradients(base, theta, weights);
    ASSERT_EQ(gradient.rows(), n);
    ASSERT_EQ(gradient.cols(), 2);
    const double h = causality == Causality::kForceInput ? 1.0 : 1e-6;  // N, m
    for (int k = 0; k < 3; ++k) {
      const auto [sp, sm] = SolveMovedBothWays(solver, input, theta, base, h * directions.col(k));
      for (int b = 0; b < 2; ++b) {
        // Tolerance relative to the sum's terms before they cancel.
        double numeric = 0.0, terms = 0.0;
        for (int c = 0; c < channels; ++c) {
          const Eigen::VectorXd dy = (sp.outputs.row(c) - sm.outputs.row(c)).transpose() / (2 * h);
          numeric += weights[c].col(b).dot(dy);
          terms += weights[c].col(b).cwiseAbs().dot(dy.cwiseAbs());
        }
        const double exact = gradient.col(b).dot(directions.col(k));
        EXPECT_NEAR(exact, numeric, 1e-4 * terms + 1e-12) << "functional " << b << " direction " << k;
      }
    }
  });
}

TEST(PeriodicSolver, InputSensitivitiesMatchFiniteDifferencesOfTheSolver) {
  // The forward counterpart of the adjoint: outputs moved along input directions (a mean shift, a
  // low and a high harmonic) against solves with the input perturbed both ways, and the adjoint's
  // functional read off the forward sensitivities.
  ForEachInputDerivativeCase([](const InputDerivativeCase& at) {
    const auto& [causality, theta, n, input, solver, base] = at;
    const Eigen::MatrixXd directions = InputDirections(n, 17);
    const auto sens = solver.InputSensitivities(base, theta, directions);
    ASSERT_EQ(sens.size(), base.channels.size());
    const double h = causality == Causality::kForceInput ? 0.25 : 1e-6;  // N, m (1 N: truncation 9e-4 in T)  // N, m
    for (int k = 0; k < 3; ++k) {
      const auto [sp, sm] = SolveMovedBothWays(solver, input, theta, base, h * directions.col(k));
      for (std::size_t c = 0; c < base.channels.size(); ++c) {
        const int row = static_cast<int>(c);
        const Eigen::VectorXd numeric = (sp.outputs.row(row) - sm.outputs.row(row)).transpose() / (2 * h);
        const Eigen::VectorXd exact = sens[c].col(k);
        const double size = std::max(exact.cwiseAbs().maxCoeff(), 1e-30);
        EXPECT_LT((numeric - exact).cwiseAbs().maxCoeff(), 2e-4 * size + 1e-12)
            << base.channels[c] << " direction " << k;
      }
    }
    // The adjoint agrees: w^T (dy/du phi) = (d(w^T y)/du)^T phi.
    std::vector<Eigen::MatrixXd> weights(base.channels.size(), Eigen::MatrixXd::Zero(n, 1));
    double forward = 0.0, scale = 0.0;
    for (std::size_t c = 0; c < base.channels.size(); ++c) {
      const double size = std::max(base.outputs.row(static_cast<int>(c)).cwiseAbs().maxCoeff(), 1e-30);
      for (int mu = 0; mu < n; ++mu) weights[c](mu, 0) = std::cos(2 * std::numbers::pi * (c + 2) * mu / n) / size;
      forward += weights[c].col(0).dot(sens[c].col(2));
      scale += weights[c].col(0).cwiseAbs().dot(sens[c].col(2).cwiseAbs());
    }
    const Eigen::MatrixXd gradient = solver.InputGradients(base, theta, weights);
    EXPECT_NEAR(gradient.col(0).dot(directions.col(2)), forward, 1e-9 * scale + 1e-15);
  });
}

TEST(PeriodicSolver, SensitivitiesMatchFiniteDifferencesOfTheSolver) {
  for (Causality causality : {Causality::kForceInput, Causality::kStrokeInput}) {
    SCOPED_TRACE(std::string(ToString(causality)));
    const Model model = Model::Build("2dof", causality);
    const auto theta = model.defaults().values();
    const PeriodicInput input = TwoDofInput(causality, theta, 200);
    // Differences of the solver need it converged far below the effect of the step h.
    const Scheme scheme = PeriodicSolverOptions{}.scheme;
    PeriodicSolver solver = TightSolver(model, scheme);
    const PeriodicSolution base = solver.Solve(input, theta);
    const auto sens = solver.OutputSensitivities(base, theta);
    ASSERT_EQ(sens.size(), base.channels.size());
    for (int i = 0; i < model.parameter_count(); ++i) {
      const double h = 1e-5 * std::max(std::abs(theta[i]), model.defaults().spec(i).typical_size());
      auto plus = theta, minus = theta;
      plus[i] += h;
      minus[i] -= h;
      PeriodicSolver fd_solver = TightSolver(model, scheme);
      const PeriodicSolution sp = fd_solver.Solve(input, plus, &base);
      const PeriodicSolution sm = fd_solver.Solve(input, minus, &base);
      for (std::size_t c = 0; c < base.channels.size(); ++c) {
        const Eigen::VectorXd numeric =
            (sp.outputs.row(static_cast<int>(c)) - sm.outputs.row(static_cast<int>(c))).transpose() / (2 * h);
        const Eigen::VectorXd exact = sens[c].col(i);
        const double size = std::max(exact.cwiseAbs().maxCoeff(), 1e-30);
        EXPECT_LT((numeric - exact).cwiseAbs().maxCoeff(), 2e-4 * size + 1e-12)
            << base.channels[c] << " w.r.t. " << model.defaults().spec(i).key();
      }
    }
  }
}

TEST(PeriodicSolver, NoPeriodicSolutionEndsWithAClearError) {
  // A stroke beyond full compression (1 + theta6 q < 0): no physical gas state exists.
  PeriodicSolver solver(Model::Build("1dof", Causality::kStrokeInput));
  const auto theta = Model::Build("1dof", Causality::kStrokeInput).defaults().values();
  try {
    solver.Solve(PeriodicInput::Sine(0.5, 0.33, 0.05, 200), theta);
    FAIL() << "expected PeriodicSolverError";
  } catch (const PeriodicSolverError& e) {
    EXPECT_NE(std::string(e.what()).find("periodic solver"), std::string::npos) << e.what();
  } catch (const std::exception& e) {
    FAIL() << "wrong exception: " << e.what();
  }
  // Too few iterations: the message gives the residual reached.
  PeriodicSolverOptions options;
  options.max_iterations = 1;
  options.start_up_periods = 0;
  PeriodicSolver hurried(Model::Build("2dof", Causality::kForceInput), options);
  PeriodicSolver stroke_solver(Model::Build("2dof", Causality::kStrokeInput));
  const auto theta2 = Model::Build("2dof", Causality::kForceInput).defaults().values();
  const PeriodicInput force = ForceOf(stroke_solver.Solve(PeriodicInput::Sine(0.1, 0.133, 0.127, 400), theta2));
  try {
    hurried.Solve(force, theta2);
    FAIL() << "expected PeriodicSolverError";
  } catch (const PeriodicSolverError& e) {
    EXPECT_NE(std::string(e.what()).find("residual"), std::string::npos) << e.what();
    EXPECT_TRUE(std::isfinite(e.residual_norm));
  }
  // Bad inputs are refused before any work.
  PeriodicInput nan_input = PeriodicInput::Sine(0.5, 0.1, 0.01, 100);
  nan_input.values[7] = NAN;
  EXPECT_THROW(solver.Solve(nan_input, theta), std::invalid_argument);
  EXPECT_THROW(solver.Solve(PeriodicInput::Sine(0.0, 0.1, 0.01, 100), theta), std::invalid_argument);
  EXPECT_THROW(solver.Solve(PeriodicInput::Sine(0.5, 0.1, 0.01, 100), std::vector<double>{1.0}), std::invalid_argument);
}

TEST(PeriodicInput, PeriodAveragingRecoversTheWaveformFromANoisyRecord) {
  // 500 Hz sampling of a 0.3 Hz sine: a non-integer 1666.7 samples per period, 3 periods.
  const double fs = 500.0, f = 0.3;
  const long periods = 3;
  const int count = static_cast<int>(std::lround(periods * fs / f));
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 1e-4);
  std::vector<double> record(count);
  const double phase = 0.7;  // recording starts at an arbitrary phase
  for (int i = 0; i < count; ++i) record[i] = 0.1 + 0.02 * std::sin(2 * std::numbers::pi * f * i / fs + phase) + noise(rng);
  const PeriodicInput in = PeriodicInput::FromRecord(record, fs, f, periods, 100);
  ASSERT_EQ(in.values.size(), 100u);
  for (int mu = 0; mu < 100; ++mu) {
    const double expected = 0.1 + 0.02 * std::sin(2 * std::numbers::pi * mu / 100.0 + phase);
    EXPECT_NEAR(in.values[mu], expected, 4e-4);
  }
  EXPECT_THROW(PeriodicInput::FromRecord(std::vector<double>(10, 0.0), fs, f, periods, 100), std::invalid_argument);
}

}  // namespace
}  // namespace strut::ident
