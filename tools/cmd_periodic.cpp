// strut periodic: one period of the periodic equilibrium state of a model.
#include <spdlog/spdlog.h>

#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "model_options.h"
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

  void Run() const {
    const ident::Model m = model.BuildModel();
    const ident::ParameterSet parameters = model.Parameters(m);
    ident::PeriodicSolverOptions options;
    options.scheme = ident::ParseScheme(scheme);
    ident::PeriodicSolver solver(m, options);
    const ident::PeriodicInput input = Input(m);
    const ident::PeriodicSolution solution = solver.Solve(input, parameters.values());
    spdlog::info("{} ({} input), {} at n = {}: {} Newton iterations, scaled residual {:.3g}", m.composition(),
                 ident::ToString(m.causality()), scheme, n, solution.newton_iterations, solution.residual_norm);

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
    std::ofstream out(json_path);
    out << j.dump(1) << "\n";
    if (!out) throw std::runtime_error("cannot write " + json_path);
    spdlog::info("wrote {}", json_path);
  }
};

}  // namespace

void RegisterPeriodicCommand(CLI::App& app) {
  auto command = std::make_shared<PeriodicCommand>();
  CLI::App* sub = app.add_subcommand("periodic", "Compute one period of the periodic equilibrium state of a model");
  command->model.Add(*sub);
  auto* f = sub->add_option("--frequency", command->frequency, "Excitation frequency (Hz)")->capture_default_str();
  auto* a = sub->add_option("--amplitude", command->amplitude,
                            "Input amplitude: m with --input stroke, N with --input force");
  auto* s = sub->add_option("--static", command->static_value,
                            "Input mean: static position (m) or static force (N)");
  sub->add_option("--from", command->from, "Use the period-averaged measured input of SESSION:EXPERIMENT")
      ->excludes(f)
      ->excludes(a)
      ->excludes(s);
  sub->add_option("--n", command->n, "Grid points per period")->check(CLI::Range(4, 1000000))->capture_default_str();
  sub->add_option("--scheme", command->scheme, "backward2, central2, central4 or spectral")
      ->check(CLI::IsMember({"backward2", "central2", "central4", "spectral"}))
      ->capture_default_str();
  sub->add_option("--json", command->json_path, "Write JSON to this file ('-' for stdout) instead of a CSV table");
  sub->callback([command] { command->Run(); });
}

}  // namespace strut::tools
