// strut periodic: one period of the periodic equilibrium state of a model.
#include <spdlog/spdlog.h>

#include <cmath>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "model_options.h"
#include "option_checks.h"
#include "output_files.h"
#include "strut/daq/session.h"
#include "strut/ident/periodic.h"

namespace strut::tools {
namespace {

struct PeriodicCommand {
  ModelOptions model;
  double frequency = 0.1;
  double amplitude = 0.0;
  double static_value = 0.0;
  std::string from;
  int n = 800;
  std::string scheme = "backward2";
  std::string json_path;

  ident::PeriodicInput Input(const ident::Model& m) const {
    if (from.empty()) {
      if (!(frequency > 0)) throw std::invalid_argument("--frequency must be positive");
      return ident::PeriodicInput::Sine(frequency, static_value, amplitude, n);
    }
    const auto colon = from.rfind(':');
    if (colon == std::string::npos || colon == 0 || colon + 1 == from.size())
      throw std::invalid_argument("--from takes SESSION:EXPERIMENT, got '" + from + "'");
    const std::string path = from.substr(0, colon), label = from.substr(colon + 1);
    const daq::Session session = daq::ReadSession(path);
    const daq::Experiment& e = session.experiment(label);
    if (e.kind != daq::ExperimentKind::kPeriodic)
      throw std::invalid_argument(path + ": experiment '" + label + "' is not periodic");
    const std::string channel = m.causality() == ident::Causality::kForceInput ? "force" : "stroke";
    return ident::PeriodicInput::FromRecord(e.channel(channel).samples, e.sample_rate, e.frequency, e.periods, n);
  }

  //! Refuses inputs the model cannot have a physical periodic state for, before solving: one line
  //! naming the option and its valid range.
  void Validate(const ident::Model& m, const ident::ParameterSet& parameters) const {
    const int n_min = scheme == "spectral" ? 4 : 8, n_max = 1000000;
    if (n < n_min || n > n_max)
      throw std::invalid_argument(fmt::format("--n must be in {} .. {} with --scheme {}, got {}", n_min, n_max, scheme, n));
    if (!from.empty()) return;  // a recorded input: its checks are the recording's
    if (!(frequency > 0) || !std::isfinite(frequency))
      throw std::invalid_argument(fmt::format("--frequency must be a positive number of Hz, got {}", frequency));
    const bool stroke_input = m.causality() == ident::Causality::kStrokeInput;
    const char* unit = stroke_input ? "m" : "N";
    if (!(amplitude > 0) || !std::isfinite(amplitude))
      throw std::invalid_argument(fmt::format("--amplitude must be positive (the input amplitude, {}), got {}", unit,
                                              amplitude));
    if (!std::isfinite(static_value))
      throw std::invalid_argument(fmt::format("--static must be finite, got {}", static_value));
    if (!stroke_input) {
      if (!(static_value > 0))
        throw std::invalid_argument(
            fmt::format("--static must be a positive static force (N, compression-positive) with --input force, got {}",
                        static_value));
      return;
    }
    // Stroke input: the measured stroke is q + theta12, and q must stay inside the damper.
    if (m.output_channels().front() != "stroke") return;  // not a damper: no stroke range
    const int offset_position = m.defaults().position_of_index(12);
    const double offset = offset_position >= 0 ? parameters.value(offset_position) : 0.0;
    const double low = offset, high = ident::kDamperStroke + offset;
    if (static_value - amplitude < low || static_value + amplitude > high)
      throw std::invalid_argument(fmt::format(
          "--static {} ± --amplitude {} leaves the damper's stroke: static ± amplitude must lie in {:.4g} .. {:.4g} m{}",
          static_value, amplitude, low, high,
          offset != 0 ? fmt::format(" (the damper's stroke 0 .. {} m shifted by the stroke offset theta12 = {:.4g} m)",
                                    ident::kDamperStroke, offset)
                      : std::string(" (the damper's stroke)")));
  }

  void Run() const {
    // The output is checked before the work: never one of the inputs, and its folder must exist.
    if (json_path != "-") {
      std::vector<std::string> inputs;
      if (!model.params_file.empty()) inputs.push_back(model.params_file);
      if (const auto colon = from.rfind(':'); colon != std::string::npos) inputs.push_back(from.substr(0, colon));
      CheckOutputPath("--json", json_path, inputs);
    }
    const ident::Model m = model.BuildModel();
    const ident::ParameterSet parameters = model.Parameters(m);
    Validate(m, parameters);
    ident::PeriodicSolverOptions options;
    options.scheme = ident::ParseScheme(scheme);
    ident::PeriodicSolver solver(m, options);
    const ident::PeriodicInput input = Input(m);
    const ident::PeriodicSolution solution = solver.Solve(input, parameters.values());
    // The solver converges on the size of the Newton step (each unknown's scale times the
    // tolerance), not on the residual, whose scale under steep friction is arbitrary. Check the
    // same at the solution it returned: the correction its Jacobian makes of the residual there.
    Eigen::MatrixXd correction = -solver.Residual(solution.unknowns, input, parameters.values());
    const double residual_at_solution = correction.size() > 0 ? correction.cwiseAbs().maxCoeff() : 0.0;
    if (solution.solver_state.jacobian)
      solution.solver_state.jacobian->Solve(Eigen::Map<Eigen::VectorXd>(correction.data(), correction.size()));
    double step_left = solution.solver_state.jacobian ? 0.0 : INFINITY;
    for (int j = 0; j < correction.rows() && solution.solver_state.jacobian; ++j)
      step_left = std::max(step_left, correction.row(j).cwiseAbs().maxCoeff() /
                                          (m.unknown_spec(j).scale * options.tolerance));
    spdlog::info("{} ({} input), {} at n = {}: {} Newton iterations, scaled residual {:.3g}, Newton step left {:.3g} "
                 "of the tolerance",
                 m.composition(), ident::ToString(m.causality()), scheme, n, solution.newton_iterations,
                 residual_at_solution, step_left);
    if (const auto violation = ident::PhysicalViolation(m, solution, parameters.values()))
      throw std::runtime_error("no physical periodic solution: " + *violation);
    if (!(step_left <= 1.0))
      throw std::runtime_error(fmt::format(
          "no periodic solution: Newton did not converge; at the state it returned the next Newton step is {:.3g} "
          "times the solver's tolerance (scaled residual {:.3g})",
          step_left, residual_at_solution));

    const std::vector<double> time = solution.time();
    if (json_path.empty()) {
      std::cout << "time_s";
      for (const auto& c : solution.channels) std::cout << "," << c << "_" << m.channel_unit(c);
      std::cout << "\n";
      for (int mu = 0; mu < solution.n; ++mu) {
        std::cout << fmt::format("{:.9g}", time[mu]);
        for (int c = 0; c < solution.outputs.rows(); ++c) std::cout << fmt::format(",{:.9g}", solution.outputs(c, mu));
        std::cout << "\n";
      }
      return;
    }
    nlohmann::json j;
    j["model"] = m.composition();
    j["input"] = ident::ToString(m.causality());
    j["scheme"] = scheme;
    j["n"] = solution.n;
    j["frequency"] = solution.frequency;
    j["time"] = time;
    for (std::size_t c = 0; c < solution.channels.size(); ++c) {
      const Eigen::VectorXd row = solution.outputs.row(static_cast<int>(c));
      j[solution.channels[c]] = std::vector<double>(row.data(), row.data() + row.size());
    }
    j["units"] = nlohmann::json::object();
    for (const auto& c : solution.channels) j["units"][c] = m.channel_unit(c);
    j["newton_iterations"] = solution.newton_iterations;
    j["residual_norm"] = solution.residual_norm;
    nlohmann::json params = nlohmann::json::array();
    for (int i = 0; i < parameters.size(); ++i)
      params.push_back({{"index", parameters.spec(i).key()},
                        {"name", parameters.spec(i).name},
                        {"unit", parameters.spec(i).unit},
                        {"value", parameters.value(i)}});
    j["parameters"] = params;
    if (json_path == "-") {
      std::cout << j.dump(1) << "\n";
      return;
    }
    WriteJsonOutput(json_path, j);
  }
};

}  // namespace

void RegisterPeriodicCommand(CLI::App& app) {
  auto [sub, command] = AddCommand<PeriodicCommand>(app, "periodic",
                                                    "Compute one period of a model's periodic equilibrium state under "
                                                    "a sine input (or a recorded one) and print it as CSV or JSON.");
  command->model.Add(*sub);
  auto* f = sub->add_option("--frequency", command->frequency, "The excitation frequency in Hz.")->check(Positive("Hz"))->capture_default_str();
  auto* a = sub->add_option("--amplitude", command->amplitude,
                            "The input's amplitude: in m with --input stroke, in N with --input force. It must be positive.");
  auto* s = sub->add_option("--static", command->static_value,
                            "The input's mean: the static position in m (within the damper's stroke) with --input stroke, the static force in N (positive: compression) with --input force.");
  sub->add_option("--from", command->from, "Drive the model with the period-averaged measured input of experiment EXPERIMENT in session file SESSION (SESSION:EXPERIMENT) instead of a sine.")
      ->excludes(f)
      ->excludes(a)
      ->excludes(s);
  sub->add_option("--n", command->n, "Grid points per period (at least 8 for the difference schemes, 4 for spectral).")->check(Between(4, 1000000))->capture_default_str();
  sub->add_option("--scheme", command->scheme, "The difference scheme: backward2, central2, central4 or spectral (docs/periodic-solver.md).")
      ->check(CLI::IsMember({"backward2", "central2", "central4", "spectral"}))
      ->capture_default_str();
  sub->add_option("--json", command->json_path, "Write the state as JSON to this file ('-' for stdout) instead of printing a CSV table.");
}

}  // namespace strut::tools
