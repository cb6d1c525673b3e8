// strut demo: the main job on the simulated rig. Until the simulated rig and the estimator land it
// computes the periodic equilibrium states of the 2 dof model for the standard test matrix.
#include <spdlog/spdlog.h>

#include <chrono>
#include <iostream>

#include "commands.h"
#include "model_options.h"
#include "strut/ident/periodic.h"
#include "strut/rig/test_matrix.h"

namespace strut::tools {
namespace {

struct DemoCommand {
  ModelOptions model;
  int n = 800;

  void Run() const {
    const ident::Model m = model.BuildModel();
    const ident::ParameterSet parameters = model.Parameters(m);
    spdlog::info("periodic equilibrium states of {} ({} input), n = {}, parameters:\n{}", m.composition(),
                 ident::ToString(m.causality()), n, parameters.table());
    // The matrix prescribes strokes; a force-driven run is fed the force of the stroke-driven solution.
    ident::PeriodicSolver stroke_solver(ident::Model::Build(model.composition, ident::Causality::kStrokeInput));
    ident::PeriodicSolver solver(m);
    std::cout << fmt::format("{:<3} {:<6} {:>6} {:>7} {:>7} | {:>15} | {:>15} | {:>15} | {:>4} {:>8}\n", "exp", "group",
                             "f Hz", "stat mm", "amp mm", "force kN", "pressure MPa", "gas temp C", "its", "ms");
    for (const auto& e : rig::StandardMatrix()) {
      const auto start = std::chrono::steady_clock::now();
      ident::PeriodicSolution solution =
          stroke_solver.Solve(ident::PeriodicInput::Sine(e.frequency, e.static_position, e.amplitude, n),
                              parameters.values());
      if (m.causality() == ident::Causality::kForceInput) {
        ident::PeriodicInput force{e.frequency, {}};
        const Eigen::VectorXd f = solution.channel("force");
        force.values.assign(f.data(), f.data() + f.size());
        solution = solver.Solve(force, parameters.values());
      }
      const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
      const auto range = [&](const char* channel, double scale, double offset) {
        for (std::size_t c = 0; c < solution.channels.size(); ++c)
          if (solution.channels[c] == channel)
            return fmt::format("{:7.3f}..{:7.3f}", solution.outputs.row(c).minCoeff() * scale + offset,
                               solution.outputs.row(c).maxCoeff() * scale + offset);
        return std::string("      -        ");
      };
      std::cout << fmt::format("{:<3} {:<6} {:>6.2f} {:>7.0f} {:>7.0f} | {} | {} | {} | {:>4} {:>8.2f}\n", e.label,
                               e.group, e.frequency, e.static_position * 1e3, e.amplitude * 1e3,
                               range("force", 1e-3, 0), range("pressure", 1e-6, 0),
                               range("temperature", 1.0, -273.15), solution.newton_iterations, ms);
    }
  }
};

}  // namespace

void RegisterDemoCommand(CLI::App& app) {
  auto command = std::make_shared<DemoCommand>();
  CLI::App* sub = app.add_subcommand("demo", "Run the main job on the simulated rig (standard matrix)");
  command->model.Add(*sub);
  sub->add_option("--n", command->n, "Grid points per period")->check(CLI::Range(8, 100000))->capture_default_str();
  sub->callback([command] { command->Run(); });
}

}  // namespace strut::tools
