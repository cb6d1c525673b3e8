// The periodic solver (ident::PeriodicSolver) against an independent reference: the periodic steady
// state reached by integrating in time with IDA (sim::TransientSimulator::PeriodicSteadyState).
// The difference is the discretisation error of the scheme; its observed order is asserted.
// docs/transient.md lists the measured errors.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <map>

#include "strut/sim/transient.h"
#include "transient_reference.h"

namespace strut::sim {
namespace {

using ident::Causality;
using ident::Model;
using ident::PeriodicInput;
using ident::Scheme;

// Standard-matrix experiment h: 0.5 Hz, 133 mm static, 34 mm amplitude.
constexpr double kFrequency = 0.5, kStatic = 0.133, kAmplitude = 0.034;

// The reference: IDA at the reference tolerances (test::ReferenceTolerances) and periods compared
// to 0.1 of the scales; its error is a few 1e-9 of a channel's range (the gas
// temperature, whose scale 1e-6 K is 5e-8 of its 20 K range, converges slowest).
PeriodicSteadyStateResult Reference(const Model& model, const PeriodicInput& input) {
  SteadyStateOptions steady;
  steady.tol = 0.1;
  steady.periods_max = 400;
  return TransientSimulator(model, test::ReferenceTolerances())
      .PeriodicSteadyState(model.defaults().values(), input, steady);
}

struct Error {
  double max = 0.0;  //!< largest |periodic - reference| over the grid and channels, / channel range
  double rms = 0.0;  //!< largest RMS over the grid of a channel, / channel range
};

// The periodic solution on n points against the reference on a multiple of n.
Error Compare(const ident::PeriodicSolution& s, const ident::PeriodicSolution& reference) {
  EXPECT_EQ(reference.n % s.n, 0);
  const int stride = reference.n / s.n;
  Error e;
  for (int c = 0; c < s.outputs.rows(); ++c) {
    const Eigen::VectorXd ref = reference.outputs.row(c).transpose();
    const double range = ref.maxCoeff() - ref.minCoeff();
    if (!(range > 0)) continue;  // the input channel, identical by construction
    double max = 0.0, sum = 0.0;
    for (int mu = 0; mu < s.n; ++mu) {
      const double d = std::abs(s.outputs(c, mu) - ref[mu * stride]);
      max = std::max(max, d);
      sum += d * d;
    }
    e.max = std::max(e.max, max / range);
    e.rms = std::max(e.rms, std::sqrt(sum / s.n) / range);
  }
  return e;
}

// Least-squares slope of -log(error) against log(n): the observed order of convergence.
double FittedOrder(const std::vector<int>& ns, const std::vector<double>& errors) {
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  const double k = static_cast<double>(ns.size());
  for (std::size_t i = 0; i < ns.size(); ++i) {
    const double x = std::log(ns[i]), y = -std::log(errors[i]);
    sx += x;
    sy += y;
    sxx += x * x;
    sxy += x * y;
  }
  return (k * sxy - sx * sy) / (k * sxx - sx * sx);
}

// Errors of one scheme at several n against the reference; printed, as the docs quote them.
std::vector<Error> Errors(const Model& model, Scheme scheme, const std::vector<int>& ns,
                          const std::function<PeriodicInput(int)>& input, const PeriodicSteadyStateResult& reference) {
  ident::PeriodicSolverOptions options;
  options.scheme = scheme;
  ident::PeriodicSolver solver(model, options);
  std::vector<Error> errors;
  for (int n : ns) {
    const Error e = Compare(solver.Solve(input(n), model.defaults().values()), reference.solution);
    std::printf("  %s %s %-9s n = %4d: max %.3e  rms %.3e\n", model.composition().c_str(),
                std::string(ToString(model.causality())).c_str(), std::string(ToString(scheme)).c_str(), n, e.max,
                e.rms);
    errors.push_back(e);
  }
  return errors;
}

std::vector<double> Max(const std::vector<Error>& e) {
  std::vector<double> v;
  for (const auto& x : e) v.push_back(x.max);
  return v;
}
std::vector<double> Rms(const std::vector<Error>& e) {
  std::vector<double> v;
  for (const auto& x : e) v.push_back(x.rms);
  return v;
}

constexpr bool kRmsNorm = true, kMaxNorm = false;

// The order the errors of `scheme` on ns converge at, in the RMS or the max norm: printed as the
// docs quote it, and expected within (low, high).
void ExpectOrder(Scheme scheme, const std::vector<int>& ns, const std::vector<Error>& errors, bool rms, double low,
                 double high) {
  const std::string name(ToString(scheme));
  SCOPED_TRACE(name);
  const double order = FittedOrder(ns, rms ? Rms(errors) : Max(errors));
  std::printf("  %s order (%s) %.2f\n", name.c_str(), rms ? "rms" : "max", order);
  EXPECT_GT(order, low);
  EXPECT_LT(order, high);
}

PeriodicInput StrokeSine(int n) { return PeriodicInput::Sine(kFrequency, kStatic, kAmplitude, n); }

// The force of a stroke-driven periodic solution (spectral, 64 points) as a smooth force input:
// its trigonometric interpolant, sampled on any grid finer than 64 points, is one and the same
// function, so every n and the reference see the same input.
std::function<PeriodicInput(int)> ForceOfStrokeSolution(const std::string& composition) {
  const Model stroke_model = Model::Build(composition, Causality::kStrokeInput);
  ident::PeriodicSolverOptions options;
  options.scheme = Scheme::kSpectral;
  const auto solution = ident::PeriodicSolver(stroke_model, options).Solve(StrokeSine(64), stroke_model.defaults().values());
  const Eigen::VectorXd force = solution.channel("force");
  const InputSignal signal =
      InputSignal::FromPeriodic(PeriodicInput{kFrequency, std::vector<double>(force.begin(), force.end())});
  return [signal](int n) {
    PeriodicInput in{kFrequency, std::vector<double>(n)};
    for (int mu = 0; mu < n; ++mu) in.values[mu] = signal(mu / (n * kFrequency)).value;
    return in;
  };
}

void PrintReference(const char* what, const PeriodicSteadyStateResult& r) {
  std::printf("%s: reference after %d periods, %ld IDA steps, %.2f s, estimated error %.2g scaled units\n", what,
              r.periods, r.steps, r.wall_seconds, r.estimated_error);
}

// Stroke input: the discretisation error comes from the input derivatives (stencil applied to the
// measured stroke) and, in the 2dof model, from the heat balance. The friction term makes the force
// very sensitive to q' near the reversals, where the O(h^2) error of backward differences vanishes
// (q''' = 0 there); the max norm is dominated by the O(h^3) term there up to n of a few thousand,
// so the second order shows in the RMS norm, asymptotic from n = 400.
void CheckStrokeDriven(const std::string& composition, double spectral_bound) {
  const Model model = Model::Build(composition, Causality::kStrokeInput);
  const auto reference = Reference(model, StrokeSine(3200));
  PrintReference(composition.c_str(), reference);

  const std::vector<int> backward_n = {400, 800, 1600};
  const auto backward = Errors(model, Scheme::kBackward2, backward_n, StrokeSine, reference);
  ExpectOrder(Scheme::kBackward2, backward_n, backward, kRmsNorm, 1.7, 2.3);
  EXPECT_LT(backward[1].max, 5e-6) << "the paper's n = 800";

  const std::vector<int> central_n = {50, 100, 200};
  const auto central = Errors(model, Scheme::kCentral4, central_n, StrokeSine, reference);
  ExpectOrder(Scheme::kCentral4, central_n, central, kMaxNorm, 3.6, 4.4);

  // Spectral: exact derivatives of the sine input, a smooth temperature; at the reference's own
  // error from 32 points on.
  const auto spectral = Errors(model, Scheme::kSpectral, {16, 32, 64}, StrokeSine, reference);
  EXPECT_LT(spectral[0].max, 10 * spectral_bound);
  EXPECT_LT(spectral[1].max, spectral_bound);
  EXPECT_LT(spectral[2].max, spectral_bound);
  EXPECT_LT(spectral[1].max, central[2].max) << "32 spectral points beat 200 fourth-order ones";
}

TEST(PeriodicVsTransient, StrokeDriven2dofConvergesAtTheOrderOfEachScheme) { CheckStrokeDriven("2dof", 1e-8); }

TEST(PeriodicVsTransient, StrokeDriven1dofConvergesAtTheOrderOfEachScheme) { CheckStrokeDriven("1dof", 1e-10); }

// Force input: the stroke sticks near the reversals (smooth atan friction, theta10 = 2000 s/m), a
// feature of a few milliseconds that the grid resolves only from n of about 800 on; from there the
// schemes converge at their order. Spectral collocation does not converge at affordable n here.
// ForceDriven: the force-driven model of a composition, its transient reference on 3200 points and
// the grids compared with it.
struct ForceDriven {
  explicit ForceDriven(const std::string& composition)
      : model(Model::Build(composition, Causality::kForceInput)),
        input(ForceOfStrokeSolution(composition)),
        reference(Reference(model, input(3200))) {
    PrintReference((composition + " force").c_str(), reference);
  }

  // The errors of `scheme` on the grids, expected to converge in the RMS norm at an order in (low, high).
  std::vector<Error> ExpectOrderOf(Scheme scheme, double low, double high) const {
    const auto errors = Errors(model, scheme, ns, input, reference);
    ExpectOrder(scheme, ns, errors, kRmsNorm, low, high);
    return errors;
  }

  const Model model;
  const std::function<PeriodicInput(int)> input;
  const PeriodicSteadyStateResult reference;
  const std::vector<int> ns = {800, 1600, 3200};
};

TEST(PeriodicVsTransient, ForceDriven2dofConvergesAtTheOrderOfEachScheme) {
  const ForceDriven force("2dof");
  const auto backward = force.ExpectOrderOf(Scheme::kBackward2, 1.7, 2.3);
  EXPECT_LT(backward[0].max, 5e-4) << "the paper's n = 800";
  force.ExpectOrderOf(Scheme::kCentral4, 3.4, 4.6);
}

TEST(PeriodicVsTransient, ForceDriven1dofBackwardSchemeConvergesAtSecondOrder) {
  ForceDriven("1dof").ExpectOrderOf(Scheme::kBackward2, 1.7, 2.3);
}

TEST(PeriodicVsTransient, SteadyStateDoesNotDependOnTheStart) {
  // From the static equilibrium and from a start 5 K too warm: the same period, within the
  // reference tolerance. The gas-temperature mode decays by about 0.87 per period here.
  const Model model = Model::Build("2dof", Causality::kStrokeInput);
  const auto& theta = model.defaults().values();
  const PeriodicInput input = StrokeSine(200);
  SteadyStateOptions steady;
  steady.tol = 0.1;
  const TransientSimulator simulator(model, test::ReferenceTolerances());
  const auto cold = simulator.PeriodicSteadyState(theta, input, steady);
  InitialState warm;
  warm.unknowns = model.StaticEquilibrium(input.values[0], theta);
  warm.unknowns[2] += 5.0;
  const auto hot = simulator.PeriodicSteadyState(theta, input, steady, warm);
  const Error e = Compare(hot.solution, cold.solution);
  std::printf("  steady state from two starts: max difference %.3e of the range (%d and %d periods)\n", e.max,
              cold.periods, hot.periods);
  EXPECT_LT(e.max, 3e-8);  // measured 6.5e-9; an unforgotten start would differ by far more
  EXPECT_GT(cold.periods, 20) << "the thermal mode needs many periods; fewer means the test stopped early";
  EXPECT_EQ(cold.solution.channels, model.output_channels());
  ASSERT_EQ(cold.solution.n, 200);
  EXPECT_DOUBLE_EQ(cold.solution.time()[100], 100 / (200 * kFrequency));
}

TEST(PeriodicVsTransient, SteadyStateThatIsNotReachedEndsWithATransientError) {
  const Model model = Model::Build("2dof", Causality::kStrokeInput);
  SteadyStateOptions steady;
  steady.periods_max = 3;
  try {
    TransientSimulator(model).PeriodicSteadyState(model.defaults().values(), StrokeSine(100), steady);
    FAIL() << "three periods cannot settle the gas temperature";
  } catch (const TransientError& e) {
    EXPECT_NEAR(e.time, 3.0 / kFrequency, 1e-9);
    EXPECT_NE(std::string(e.what()).find("3 periods"), std::string::npos) << e.what();
  }
  steady.periods_max = 1;
  EXPECT_THROW(TransientSimulator(model).PeriodicSteadyState(model.defaults().values(), StrokeSine(100), steady),
               std::invalid_argument);
}

}  // namespace
}  // namespace strut::sim
