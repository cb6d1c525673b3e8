// strut predict drop: a drop test predicted from an identified model (the JSON of strut identify),
// optionally compared with a recorded drop, with what-if scaling of parameters.
// docs/drop-prediction.md.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <map>
#include <optional>

#include "commands.h"
#include "predict_command.h"
#include "output_files.h"
#include "strut/daq/session.h"
#include "strut/ident/fit_record.h"
#include "strut/report/drop_report.h"
#include "strut/sim/drop_prediction.h"
#include "strut/sim/recorded_truth.h"
#include "option_checks.h"

namespace strut::tools {
namespace {

//! "theta3=2,theta8=0.5" (repeatable option values joined) into parameter positions and factors.
std::map<int, double> ParseScales(const std::vector<std::string>& items, const ident::ParameterSet& parameters) {
  std::map<int, double> scales;
  for (const std::string& item : items) {
    const auto eq = item.find('=');
    if (eq == std::string::npos)
      throw std::invalid_argument(fmt::format("--scale {}: expected NAME=FACTOR (e.g. theta3=2)", item));
    const std::string name = item.substr(0, eq);
    const auto position = parameters.find(name);
    if (!position) throw std::invalid_argument(fmt::format("--scale {}: the fitted model has no parameter {}", item, name));
    double factor = NAN;
    try {
      std::size_t used = 0;
      factor = std::stod(item.substr(eq + 1), &used);
      if (used != item.size() - eq - 1) factor = NAN;
    } catch (const std::exception&) {
    }
    if (!std::isfinite(factor)) throw std::invalid_argument(fmt::format("--scale {}: the factor is not a number", item));
    if (scales.count(*position)) throw std::invalid_argument(fmt::format("--scale {}: {} is scaled twice", item, name));
    scales[*position] = factor;
  }
  return scales;
}

}  // namespace

report::DropComparison PredictDropCommand::Predict() const {
std::optional<double> mass = this->mass, velocity = this->velocity, duration = this->duration;
sim::DropPredictionOptions options = this->options;
  std::vector<std::string> inputs{fit_path};
  if (!compare_path.empty()) inputs.push_back(compare_path);
  CheckOutputPath("--json", json_path, inputs);
  CheckOutputPath("--report", report_path, inputs);
  if (!json_path.empty() && json_path == report_path)
    throw std::invalid_argument("--json and --report name the same file " + json_path);

  const ident::FitRecord fit = ident::ReadFitJson(fit_path, ident::Causality::kForceInput);
  if (fit.verdict != "at-noise-floor")
    spdlog::warn("fit {}: verdict '{}': the model may not explain the shaker data, and the intervals assume it does",
                 fit_path, fit.verdict.empty() ? "unknown" : fit.verdict);
  const std::map<int, double> scale = ParseScales(scales, fit.parameters);

  // The recorded drop: its mass, velocity and length are the defaults of the prediction.
  std::optional<daq::Session> session;
  const daq::Experiment* recorded = nullptr;
  if (!compare_path.empty()) {
    session = daq::ReadSession(compare_path);
    recorded = &sim::FindDropExperiment(*session, experiment_label, compare_path);
    const auto differs = [](double a, double b) { return std::abs(a - b) > 1e-3 * std::max(std::abs(b), 1e-9); };
    if (mass && differs(*mass, recorded->drop_mass))
      spdlog::warn("predicting a drop of {} kg, the recorded drop '{}' is of {} kg", *mass, recorded->label,
                   recorded->drop_mass);
    if (velocity && differs(*velocity, recorded->impact_velocity))
      spdlog::warn("predicting an impact at {} m/s, the recorded drop '{}' is at {} m/s", *velocity, recorded->label,
                   recorded->impact_velocity);
    if (!mass) mass = recorded->drop_mass;
    if (!velocity) velocity = recorded->impact_velocity;
    if (!duration && !recorded->time.empty()) duration = recorded->time.back();
  }
  if (!mass || !velocity)
    throw std::invalid_argument("--mass and --velocity are needed (or --compare with a recorded drop to take them from)");
  options.duration = duration.value_or(30.0);
  options.intervals = !no_intervals;
  options.moving_mass = *sim::DropMovingMassFrom(moving_mass);

  report::DropComparison drop;
  drop.fit_path = fit_path;
  drop.model = fit.model.composition();
  drop.fit_verdict = fit.verdict;
  drop.mass = *mass;
  drop.impact_velocity = *velocity;
  drop.options = options;
  for (const auto& [position, factor] : scale) drop.scale[fit.parameters.spec(position).key()] = factor;
  spdlog::info("predicting a drop of {} kg{} at {} m/s for {} s with {} from {}", *mass,
               options.moving_mass == sim::DropMovingMass::kDroppedAlone ? "" : " carrying theta1", *velocity,
               options.duration, fit.model.composition(), fit_path);
  drop.prediction = sim::PredictDropWhatIf(fit.model, fit.parameters.values(), *mass, *velocity,
                                           fit.estimated_positions, fit.covariance, scale, options);
  const sim::DropPrediction& predicted = drop.prediction.predicted;
  for (const std::string& note : predicted.interval_notes) spdlog::info("intervals: {}", note);
  if (recorded) {
    drop.measured = sim::MeasureRecordedDrop(*recorded, fit.parameters, predicted.figures.static_stroke,
                                             options.settle_band);
    drop.measured_session = compare_path;
    drop.measured_experiment = recorded->label;
  }
  if (session) {
    if (const auto truth = sim::ReadRecordedTruth(*session))
      drop.missing =
          sim::AttributeMissingPhysics(truth->composition, truth->parameters, fit.model, *mass, *velocity, options);
  }
  if (!json_path.empty()) WriteJsonOutput(json_path, report::DropJson(drop));
  if (!report_path.empty()) {
    report::WriteDropReport(drop, report_path);
    spdlog::info("wrote {}", report_path);
  }
  return drop;
}

void PredictDropCommand::Run() const {
  const report::DropComparison drop = Predict();
  const sim::DropPrediction& predicted = drop.prediction.predicted;

  const report::DropTable table = report::DropFigureTable(drop);
  for (const std::string& cell : table.header) std::cout << fmt::format("{:<22}", cell);
  std::cout << "\n";
  for (const auto& row : table.rows) {
    for (const auto& cell : row) std::cout << fmt::format("{:<22}", cell);
    std::cout << "\n";
  }
  for (const sim::MissingPhysics& x : drop.missing)
    std::cout << fmt::format("the truth has {}, the fitted model not: {}\n", x.term, x.affects);
  std::cout << fmt::format("{} transient run(s), the prediction itself {:.3f} s ({} IDA steps), all {:.3f} s\n",
                           predicted.simulations, predicted.nominal_seconds, predicted.ida_steps, predicted.seconds);
}

void RegisterPredictCommand(CLI::App& app) {
  CLI::App* predict = app.add_subcommand("predict", "Predictions from an identified model");
  predict->require_subcommand(1);
  auto [sub, command] = AddCommand<PredictDropCommand>(
      *predict, "drop",
      "Drop test predicted from a fit (strut identify --json): figures with intervals, optionally compared "
      "with a recorded drop (docs/drop-prediction.md)");
  AddPredictDropOptions(*sub, *command);
}

void AddPredictDropOptions(CLI::App& app, PredictDropCommand& predict) {
  CLI::App* sub = &app;
  PredictDropCommand* command = &predict;
  sub->add_option("--fit", command->fit_path, "The fit's JSON (strut identify --json).")->required()->check(CLI::ExistingFile);
  sub->add_option("--mass", command->mass, "Dropped mass, kg (default with --compare: the record's).")
      ->check(Positive("kg"));
  sub->add_option("--velocity", command->velocity, "Stroke velocity at contact, m/s (default with --compare: the record's).")
      ->check(NonNegative("m/s"));
  sub->add_option("--duration", command->duration, "Seconds simulated from contact (default 30, or the record's length).")
      ->check(Between(1e-3, 3600.0, "s"));
  sub->add_option("--compare", command->compare_path, "A recorded drop (session HDF5) to compare with.")
      ->check(CLI::ExistingFile);
  sub->add_option("--experiment", command->experiment_label, "The drop experiment's label when the session has several.");
  sub->add_option("--scale", command->scales, "What-if: multiply a parameter, NAME=FACTOR (e.g. theta3=2); repeatable.")
      ->delimiter(',');
  sub->add_option("--json", command->json_path, "Write the figures as JSON to this file.");
  sub->add_option("--report", command->report_path, "Write a self-contained HTML report to this file.");
  sub->add_option("--rate", command->options.output_rate, "Samples per second of the predicted trace.")
      ->check(Between(1.0, 1e6, "Hz"))
      ->capture_default_str();
  sub->add_option("--settle-band", command->options.settle_band,
                  "The band that counts as static for time_to_static: the stroke within this fraction of the static stroke.")
      ->check(Between(1e-6, 0.5))
      ->capture_default_str();
  sub->add_option("--moving-mass", command->moving_mass,
                  "Which mass moves in the drop: dropped (the dropped mass alone; theta1, the shaker's moving mass, stays on "
                  "the ground) or dropped+theta1 (the dropped mass carries theta1); docs/drop-prediction.md.")
      ->check(CLI::IsMember({"dropped", "dropped+theta1"}))
      ->capture_default_str();
  sub->add_flag("--no-intervals", command->no_intervals, "Skip the intervals (one transient run instead of 1 + 2 per parameter).");
}

}  // namespace strut::tools
