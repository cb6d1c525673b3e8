// strut discover: find the physics a model leaves out, add it, and show the fit improve.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <iostream>

#include "commands.h"
#include "discover_command.h"
#include "model_options.h"
#include "option_checks.h"
#include "output_files.h"
#include "rig_run_request.h"
#include "strut/daq/session.h"
#include "strut/ident/discover.h"
#include "strut/report/discover_report.h"
#include "strut/rig/safety.h"
#include "strut/rig/test_matrix.h"

namespace strut::tools {

// The first ambiguity's decisive test as a one-experiment matrix file, written only when the matrix
// check passes against the limits (the rig would refuse it otherwise).
bool DiscoverCommand::WriteProposedTest(const ident::DiscoveryResult& result, const rig::SafetyConfig& limits,
                                        const std::string& path) const {
  const ident::Ambiguity* ambiguity = ident::DecidableAmbiguity(result);
  if (!ambiguity) {
    spdlog::warn("{} not written: no two explanations of these data fit alike, there is nothing to decide", path);
    return false;
  }
  const ident::DecisiveTest& test = *ambiguity->test;
  const rig::MatrixPlan plan = rig::DecisiveTestPlan(test);
  const std::vector<std::string> refused = rig::CheckMatrix(plan.experiments, limits, test.sample_rate);
  if (!refused.empty()) {
    std::string why;
    for (const auto& line : refused) why += "\n  " + line;
    throw std::invalid_argument(fmt::format("{}: the test that decides {} against {} does not pass the "
                                            "matrix check against {}:{}",
                                            path, test.model_a, test.model_b, limits_path.empty() ? "the default limits" : limits_path,
                                            why));
  }
  WriteTextOutput(path,
                  rig::MatrixFileText(plan, fmt::format("strut discover: the test that decides {} against {}\n{}.\n"
                                                        "Run it with `strut rig run --matrix FILE`.",
                                                        test.model_a, test.model_b, test.Describe())));
  return true;
}

std::string DiscoverCommand::MatrixPath() const {
  if (!propose_test_path.empty() || decide_path.empty()) return propose_test_path;
  const std::string stem = decide_path.size() > 3 && decide_path.ends_with(".h5") ? decide_path.substr(0, decide_path.size() - 3)
                                                                                 : decide_path;
  return stem + "-matrix.toml";
}

ident::DiscoveryResult DiscoverCommand::Discover() const {
  CheckOutputPath("--json", json_path, sessions);
  CheckOutputPath("--report", report_path, sessions);
  CheckOutputPath("--propose-test", MatrixPath(), sessions);
  if (!decide_path.empty()) {
    if (rig_spec.empty())
      throw std::invalid_argument("--decide: give the rig to run the decisive test on (--rig sim, or --rig "
                                  "modbus-tcp://HOST:PORT --daq ...)");
    CheckOutputPath("--decide", decide_path, sessions, force);
  }
  const rig::SafetyConfig limits = limits_path.empty() ? rig::SafetyConfig{} : rig::ReadSafetyConfig(limits_path);
  const ident::SessionFitOptions fit = model.FitOptions(n);
  const ident::FitData data = ident::ReadFitData(sessions, model.BuildModel(), n, fit.exclude);
  for (const auto& line : data.excluded) spdlog::info("{}", line);
  ident::DiscoverOptions options;
  options.threads = threads;
  // A decisive test may go wherever the rig's limits allow, not only where the matrix went.
  if (!data.experiments.empty()) options.test_space = rig::DecisiveTestSpace(data.experiments, limits);
  ident::DiscoveryResult result = ident::Discover(data, fit, options);
  const std::string matrix = MatrixPath();
  if (!matrix.empty() && WriteProposedTest(result, limits, matrix) && !decide_path.empty()) {
    // The test on the rig, then every explanation of the first ambiguity fitted with its session.
    RunMatrixOnRig({rig_spec, daq_spec, matrix, limits_path, decide_path, force, false, speed, &truth});
    std::vector<std::string> all = sessions;
    all.push_back(decide_path);
    result.decision = ident::DecideAmbiguity(result, ident::ReadFitData(all, model.BuildModel(), n, fit.exclude), fit, options);
    spdlog::info("{}", result.decision->conclusion);
  }
  if (!json_path.empty()) WriteJsonOutput(json_path, report::DiscoveryJson(result));
  if (!report_path.empty()) report::WriteDiscoveryReport(result, report_path);
  return result;
}

void DiscoverCommand::Run() const {
  const ident::DiscoveryResult result = Discover();
  // The conclusion and the steps are the data (stdout); the library logs only its progress (stderr).
  std::cout << result.conclusion << "\n";
  for (const auto& s : result.steps)
    std::cout << fmt::format("  {} {:<20} ΔBIC {:+.1f}  {}\n", s.removed ? '-' : '+', s.term, s.delta_bic, s.evidence);
  for (const auto& a : result.ambiguities)
    for (const auto& r : a.rivals)
      std::cout << fmt::format("  ? {:<20} or {}: {}\n", a.kept, r.term, r.why);
  if (result.decision) std::cout << result.decision->conclusion << "\n";
}

void RegisterDiscoverCommand(CLI::App& app) {
  auto [sub, command] = AddCommand<DiscoverCommand>(
      app, "discover",
      "Find the physics a model leaves out: fit the baseline with every parameter the data can determine, locate "
      "the mismatch, add the catalogue term that explains it (BIC and cross-validation), and show the fit improve.");
  AddDiscoverOptions(*sub, *command);
}

void AddDiscoverOptions(CLI::App& app, DiscoverCommand& discover) {
  CLI::App* sub = &app;
  DiscoverCommand* command = &discover;
  sub->add_option("sessions", command->sessions, "Session files (HDF5) to fit together.")->required()->check(CLI::ExistingFile);
  command->model.Add(*sub);
  command->model.AddSessionFit(*sub);
  sub->add_option("--json", command->json_path, "Write the findings as JSON to this file.");
  sub->add_option("--report", command->report_path, "Write a self-contained HTML report to this file.");
  sub->add_option("--propose-test", command->propose_test_path,
                  "Where two explanations fit the data alike, write the test that decides between them as a matrix "
                  "file for `strut rig run --matrix` (nothing is written when nothing is ambiguous).");
  sub->add_option("--limits", command->limits_path,
                  "The rig's limits (TOML, docs/rig-run.md) the proposed test must pass the matrix check against; "
                  "default the built-in limits.")
      ->check(CLI::ExistingFile);
  sub->add_option("--decide", command->decide_path,
                  "Run the test that decides (the matrix --propose-test writes, or DECIDE-matrix.toml beside this "
                  "session) on the rig given by --rig, record it to this session, and fit every explanation with it: "
                  "the data then choose one, or say they still cannot.");
  sub->add_option("--rig", command->rig_spec,
                  "With --decide: the rig, sim (the simulated rig in this process; its truth from --truth or --draw) "
                  "or the controller's modbus-tcp://HOST:PORT with --daq.");
  sub->add_option("--daq", command->daq_spec, "With --decide on a real or served rig: the acquisition, udp:HOST:PORT or can:IFACE.");
  sub->add_option("--speed", command->speed, "With --decide --rig sim: simulated seconds per wall second (default 50).")
      ->check(CLI::PositiveNumber);
  sub->add_flag("--force", command->force, "With --decide: replace an existing session at the --decide path.");
  command->truth.Add(*sub, /*with_actuator=*/true);
  AddFitGridOption(*sub, command->n);
  sub->add_option("--threads", command->threads, "Threads: candidate refits, cross-validation folds and the experiments of each fit side by side (the answers do not depend on it).")
      ->check(Between(1, 64))
      ->capture_default_str();
}

}  // namespace strut::tools
