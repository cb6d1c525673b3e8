// strut discover: find the physics a model leaves out, add it, and show the fit improve.
#include <spdlog/spdlog.h>

#include <iostream>

#include "commands.h"
#include "discover_command.h"
#include "model_options.h"
#include "option_checks.h"
#include "output_files.h"
#include "strut/daq/session.h"
#include "strut/ident/discover.h"
#include "strut/report/discover_report.h"

namespace strut::tools {

ident::DiscoveryResult DiscoverCommand::Discover() const {
  CheckOutputPath("--json", json_path, sessions);
  CheckOutputPath("--report", report_path, sessions);
  const ident::SessionFitOptions fit = model.FitOptions(n);
  const ident::FitData data = ident::ReadFitData(sessions, model.BuildModel(), n, fit.exclude);
  for (const auto& line : data.excluded) spdlog::info("{}", line);
  ident::DiscoverOptions options;
  options.threads = threads;
  ident::DiscoveryResult result = ident::Discover(data, fit, options);
  if (!json_path.empty()) WriteJsonOutput(json_path, report::DiscoveryJson(result));
  if (!report_path.empty()) report::WriteDiscoveryReport(result, report_path);
  return result;
}

void DiscoverCommand::Run() const {
  const ident::DiscoveryResult result = Discover();
  // The conclusion and the steps are the data (stdout); the library logs only its progress (stderr).
  std::cout << result.conclusion << "\n";
  for (const auto& s : result.steps)
    std::cout << fmt::format("  + {:<20} ΔBIC {:+.1f}  {}\n", s.term, s.delta_bic, s.evidence);
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
  AddFitGridOption(*sub, command->n);
  sub->add_option("--threads", command->threads, "Threads: candidate refits, cross-validation folds and the experiments of each fit side by side (the answers do not depend on it).")
      ->check(Between(1, 64))
      ->capture_default_str();
}

}  // namespace strut::tools
