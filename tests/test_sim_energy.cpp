// Energy bookkeeping of the simulated damper: over a steady period the work put in by the shaker
// leaves as dissipation and wall heat; over a drop the mass's work also goes into stored energy
// (gas heat, motion). The books close to the integration and quadrature error.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "strut/ident/periodic.h"
#include "strut/sim/energy.h"
#include "strut/sim/simulated_rig.h"

namespace strut::sim {
namespace {

TEST(SimEnergy, WorkInEqualsDissipationPlusWallHeatOverASteadyPeriod) {
  // The default truth (every effect), stroke-driven at experiment a (full stroke, 0.04 Hz) and h.
  const Truth truth = DefaultTruth();
  const ident::Model model = truth.BuildModel(ident::Causality::kStrokeInput);
  const std::vector<double> theta = truth.Parameters(model).values();
  for (const rig::MatrixEntry& e : {rig::MatrixEntry{"a", "middle", 0.04, 0.133, 0.127},
                                    rig::MatrixEntry{"h", "middle", 0.5, 0.133, 0.034}}) {
    // Start on the periodic solution, integrate two periods, keep the second one.
    ident::PeriodicSolverOptions o;
    o.scheme = ident::Scheme::kCentral4;
    const ident::PeriodicSolution start =
        ident::PeriodicSolver(model, o).Solve(ident::PeriodicInput::Sine(e.frequency, e.static_position, e.amplitude, 2000), theta);
    TransientOptions tight;
    tight.rtol = 1e-10;
    const InputSignal sine = InputSignal::Sine(e.frequency, e.static_position, e.amplitude);
    const double period = 1.0 / e.frequency;
    const int per_period = 40000;
    InitialState initial;
    initial.unknowns.assign(start.unknowns.col(0).data(), start.unknowns.col(0).data() + start.unknowns.rows());
    const TransientResult r = TransientSimulator(model, tight).Simulate(theta, sine, 2 * period, per_period / period, initial);
    const EnergyBudget b = ComputeEnergyBudget(model, theta, r, sine, per_period, 2 * per_period);
    std::printf("  %s: work in %.3f J = dissipated %.3f J + wall heat %.3f J + stored %.5f J; imbalance %.2e J\n",
                e.label.c_str(), b.work_in, b.dissipated, b.heat_to_wall, b.stored_change, b.imbalance());
    EXPECT_GT(b.work_in, 0.0);
    EXPECT_GT(b.dissipated, 0.0);   // friction, orifice, viscous: always a loss
    EXPECT_GT(b.heat_to_wall, 0.0);  // the gas loop's net heat leaves through the wall
    EXPECT_LT(std::abs(b.stored_change), 1e-3 * b.work_in);  // periodic
    EXPECT_LT(std::abs(b.imbalance()), 1e-4 * b.work_in);
  }
}

TEST(SimEnergy, DropWorkGoesIntoDissipationWallHeatAndStoredEnergy) {
  const SimulatedRig rig(DefaultTruth());
  std::mt19937_64 rng(1);
  DropSpec drop;
  drop.duration = 5.0;
  DropRunReport report;
  rig.RunDrop(drop, rng, &report);
  const ident::Model model = rig.truth().BuildModel(ident::Causality::kForceInput);
  std::vector<double> theta = rig.theta();
  theta[model.defaults().position_of_index(1)] = 0.0;  // the drop has no shaker fixture
  const EnergyBudget b = ComputeEnergyBudget(model, theta, report.result);
  // The mass's work: its potential energy lost plus its kinetic energy at contact.
  const double q_end = report.result.unknowns(0, report.result.time.size() - 1);
  const double v_end = report.result.rates(0, report.result.time.size() - 1);
  const double mass_work = drop.mass * (9.81 * q_end + 0.5 * (drop.impact_velocity * drop.impact_velocity - v_end * v_end));
  std::printf("  drop: work in %.3f J (mass %.3f J) = dissipated %.3f + wall heat %.3f + stored %.3f; imbalance %.2e J\n",
              b.work_in, mass_work, b.dissipated, b.heat_to_wall, b.stored_change, b.imbalance());
  EXPECT_NEAR(b.work_in, mass_work, 2e-3 * mass_work);
  EXPECT_GT(b.stored_change, 0.0);  // the gas is still warm and compressed after 5 s
  EXPECT_LT(std::abs(b.imbalance()), 2e-3 * b.work_in);
}

TEST(SimEnergy, BudgetNeedsAThermalModel) {
  const ident::Model polytropic = ident::Model::Build("1dof", ident::Causality::kForceInput);
  TransientResult empty;
  EXPECT_THROW(ComputeEnergyBudget(polytropic, polytropic.defaults().values(), empty), std::invalid_argument);
}

}  // namespace
}  // namespace strut::sim
