// strut identify: multi-experiment Bayesian identification from recorded sessions.
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <iostream>

#include "commands.h"
#include "identify_command.h"
#include "model_options.h"
#include "option_checks.h"
#include "output_files.h"
#include "strut/report/fit_report.h"
#include "strut/ident/session_fit.h"
#include "strut/sim/drop_fit.h"

namespace strut::tools {
namespace {

//! ", plus the drops a, b" (empty without drops), for the log.
std::string DropLabels(const std::vector<ident::TransientExperimentData>& drops) {
  std::string labels;
  for (const auto& d : drops) labels += (labels.empty() ? ", plus the drops " : ", ") + d.label;
  return labels;
}

}  // namespace

ident::SessionFit IdentifyCommand::Fit() const {
  // Before any work: no output may replace an input or a session.
  CheckOutputPath("--json", json_path, sessions);
  CheckOutputPath("--report", report_path, sessions);
  if (!json_path.empty() && json_path == report_path)
    throw std::invalid_argument("--json and --report name the same file " + json_path);
  ident::SessionFitOptions options = model.FitOptions(n);
  options.estimate = estimate;
  if (scheme != "auto") options.estimator.scheme = ident::ParseScheme(scheme);
  options.estimator.n = ident::FitGridPoints(n, options.estimator.scheme, options.causality);
  if (estimate_input != "auto") options.estimator.estimate_input = estimate_input == "on";
  options.estimator.input_harmonics = input_harmonics;
  // Drop experiments are fitted beside the periodic ones, predicted by sim's transient integrator.
  options.estimator.transient_predictor = sim::DropPredictorFactory();
  const ident::Model m = model.BuildModel();
  ident::FitData data = ident::ReadFitData(sessions, m, options.estimator.n, options.exclude);
  for (const auto& issue : data.issues)
    spdlog::warn("{}: experiment '{}', channel '{}': {}: {}", sessions.size() == 1 ? sessions[0] : "session",
                 issue.experiment, issue.channel, issue.kind, issue.detail);
  for (const auto& line : data.excluded) spdlog::info("{}", line);

  const bool tty = !no_progress && isatty(fileno(stderr));
  const auto progress = [&](const ident::FitProgress& p) {
    if (!tty) return;
    if (p.experiment > 0)
      std::fprintf(stderr, "\r  iteration %2d  experiment %2d of %2d   ", p.iteration, p.experiment, p.experiments);
    else
      std::fprintf(stderr, "\r  iteration %2d  loglik %.8g            \n", p.iteration, p.objective);
  };
  const ident::SessionFit fit = ident::FitPrepared(std::move(data), m, options, progress);
  if (tty) std::fprintf(stderr, "\r%60s\r", "");
  spdlog::info("{} ({} input), {} periodic experiments{}; starting values as used:", m.composition(),
               ident::ToString(m.causality()), fit.data.experiments.size(),
               DropLabels(fit.data.transients));
  for (const auto& line : fit.plan.Describe()) spdlog::info("  {}", line);
  if (!json_path.empty()) WriteJsonOutput(json_path, Json(fit));
  if (!report_path.empty()) {
    report::WriteFitReport(fit.summary, report_path, "strut identify: " + m.composition());
    spdlog::info("wrote {}", report_path);
  }
  return fit;
}

nlohmann::json IdentifyCommand::Json(const ident::SessionFit& fit) const {
  nlohmann::json j = report::FitToJson(fit.summary);
  j["sessions"] = sessions;
  j["excluded"] = model.exclude;
  return j;
}

void IdentifyCommand::Run() const {
  const ident::SessionFit fit = Fit();
  std::cout << fit.summary.FullReport();
  switch (fit.summary.Verdict()) {
    case ident::FitVerdict::kAtNoiseFloor:
      spdlog::info("{}", fit.summary.VerdictText());
      return;
    case ident::FitVerdict::kAboveNoiseFloor:
      spdlog::warn("{}", fit.summary.VerdictText());
      throw ExitCode(kExitAboveNoiseFloor);
    case ident::FitVerdict::kNotConverged:
      spdlog::error("{}", fit.summary.VerdictText());
      throw ExitCode(kExitNotConverged);
  }
}

void RegisterIdentifyCommand(CLI::App& app) {
  auto [sub, command] = AddCommand<IdentifyCommand>(
      app, "identify",
      "Estimate the damper model's parameters from recorded sessions (periodic equilibria and drop tests, all "
      "experiments at once). "
      "Exit code 0: converged at the noise floor; 3: converged but above the noise floor; 2: not converged; 1: error.");
  AddIdentifyOptions(*sub, *command);
}

void AddIdentifyOptions(CLI::App& app, IdentifyCommand& identify) {
  CLI::App* sub = &app;
  IdentifyCommand* command = &identify;
  sub->add_option("sessions", command->sessions, "Session files (HDF5) to fit together.")->required()->check(CLI::ExistingFile);
  command->model.Add(*sub);
  sub->add_option("--estimate", command->estimate,
                  "Parameters to estimate: a list such as theta4,theta6,theta16, or 'paper' for the paper's set. "
                  "Default: every parameter the data can determine, with a prior on the stroke sensor's zero.");
  command->model.AddSessionFit(*sub);
  sub->add_option("--json", command->json_path, "Write the fit as JSON to this file.");
  sub->add_option("--report", command->report_path, "Write a self-contained HTML report to this file.");
  AddFitGridOption(*sub, command->n);
  sub->add_option("--scheme", command->scheme,
                  "Difference scheme: backward2, central2, central4 or spectral (default auto: central4 under stroke "
                  "input, backward2 under force input; another scheme without --n gets 800 equidistant points).")
      ->check(CLI::IsMember({"auto", "backward2", "central2", "central4", "spectral"}))
      ->capture_default_str();
  sub->add_option("--estimate-input", command->estimate_input,
                  "Errors in variables: estimate the measured input's Fourier coefficients with the parameters "
                  "(auto: on for stroke input, off for force input).")
      ->check(CLI::IsMember({"auto", "on", "off"}))
      ->capture_default_str();
  sub->add_option("--input-harmonics", command->input_harmonics,
                  "Highest harmonic of the input estimated (capped below the record's Nyquist).")
      ->check(Between(0, 100000))
      ->capture_default_str();
  sub->add_flag("--no-progress", command->no_progress, "Do not show the progress line (it is shown only when stderr is a terminal).");
}

}  // namespace strut::tools
