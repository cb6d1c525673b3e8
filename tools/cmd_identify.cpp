// strut identify: multi-experiment Bayesian identification from recorded sessions.
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <iostream>

#include "commands.h"
#include "model_options.h"
#include "strut/daq/session.h"
#include "strut/ident/estimator.h"
#include "strut/ident/fit_report.h"
#include "strut/ident/initial_values.h"

namespace strut::tools {
namespace {

struct IdentifyCommand {
  std::vector<std::string> sessions;
  ModelOptions model;
  std::string estimate;
  std::string json_path, report_path;
  int n = 800;
  std::string scheme = "backward2";
  bool no_progress = false;

  void Run() const {
    const ident::Model m = model.BuildModel();
    ident::ParameterSet initial = model.Parameters(m);
    std::vector<ident::ParameterChoice> choices =
        estimate.empty() ? ident::DefaultChoices(m) : ident::ChoicesFromList(initial, estimate);
    if (!model.params_file.empty())
      for (const auto& entry : ident::ReadParameterFile(model.params_file)) {
        const int i = initial.position(entry.name);
        if (entry.estimate && estimate.empty()) choices[i].estimate = *entry.estimate;
        if (entry.prior_sd) choices[i].prior_sd = entry.prior_sd;
      }

    std::vector<ident::ExperimentData> data;
    std::vector<ident::DataIssue> issues;
    for (const std::string& path : sessions) {
      const daq::Session session = daq::ReadSession(path);
      auto prepared = ident::PrepareExperiments(session, m, n, &issues);
      for (auto& e : prepared) {
        const bool clash = std::any_of(data.begin(), data.end(), [&](const auto& d) { return d.label == e.label; });
        if (clash) e.label = path + ":" + e.label;  // several sessions may reuse labels
        data.push_back(std::move(e));
      }
    }
    if (data.empty()) throw std::invalid_argument("no complete periodic experiment in the given sessions");
    for (const auto& issue : issues)
      spdlog::warn("{}: experiment '{}', channel '{}': {}: {}", sessions.size() == 1 ? sessions[0] : "session",
                   issue.experiment, issue.channel, issue.kind, issue.detail);
    if (model.params_file.empty()) {
      // No parameter file: every starting value comes from the data (then --set wins).
      std::vector<std::string> log;
      initial = ident::InitialValuesFromData(m, data, &log);
      spdlog::info("starting values from the data:");
      for (const auto& line : log) spdlog::info("  {}", line);
      if (!model.assignments.empty()) initial.apply_assignments(model.assignments);
    }
    std::string estimated;
    for (int i = 0; i < initial.size(); ++i)
      if (choices[i].estimate) estimated += " " + initial.spec(i).key();
    spdlog::info("{} ({} input): {} experiments, estimating{}; the rest fixed", m.composition(),
                 ident::ToString(m.causality()), data.size(), estimated);

    ident::EstimatorOptions options;
    options.n = n;
    options.scheme = ident::ParseScheme(scheme);
    ident::Estimator estimator(m, options);
    const bool tty = !no_progress && isatty(fileno(stderr));
    const auto progress = [&](const ident::FitProgress& p) {
      if (!tty) return;
      if (p.experiment > 0)
        std::fprintf(stderr, "\r  iteration %2d  experiment %2d of %2d   ", p.iteration, p.experiment, p.experiments);
      else
        std::fprintf(stderr, "\r  iteration %2d  loglik %.8g            \n", p.iteration, p.objective);
    };
    const ident::FitSummary fit = estimator.Fit(data, initial, choices, issues, progress);
    if (tty) std::fprintf(stderr, "\r%60s\r", "");
    std::cout << fit.FullReport();
    if (!json_path.empty()) {
      std::ofstream out(json_path);
      out << ident::FitToJson(fit).dump(1) << "\n";
      if (!out) throw std::runtime_error("cannot write " + json_path);
      spdlog::info("wrote {}", json_path);
    }
    if (!report_path.empty()) {
      ident::WriteFitReport(fit, report_path, "strut identify: " + m.composition());
      spdlog::info("wrote {}", report_path);
    }
    if (!fit.IsSolutionUsable()) throw std::runtime_error("the fit gave no usable solution");
  }
};

}  // namespace

void RegisterIdentifyCommand(CLI::App& app) {
  auto command = std::make_shared<IdentifyCommand>();
  CLI::App* sub = app.add_subcommand("identify", "Estimate model parameters from recorded sessions (periodic equilibria)");
  sub->add_option("sessions", command->sessions, "Session files (HDF5)")->required()->check(CLI::ExistingFile);
  command->model.Add(*sub);
  sub->add_option("--estimate", command->estimate,
                  "Parameters to estimate, e.g. theta4,theta6,theta16 (default: the paper's set plus sensor offsets)");
  sub->add_option("--json", command->json_path, "Write the fit as JSON");
  sub->add_option("--report", command->report_path, "Write a self-contained HTML report");
  sub->add_option("--n", command->n, "Grid points per period")->check(CLI::Range(16, 100000))->capture_default_str();
  sub->add_option("--scheme", command->scheme, "backward2, central2, central4 or spectral")
      ->check(CLI::IsMember({"backward2", "central2", "central4", "spectral"}))
      ->capture_default_str();
  sub->add_flag("--no-progress", command->no_progress, "No progress display");
  sub->callback([command] { command->Run(); });
}

}  // namespace strut::tools
