// strut predict drop: a drop test predicted from an identified model (the JSON of strut identify),
// optionally compared with a recorded drop, with what-if scaling of parameters.
// docs/drop-prediction.md.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>

#include "commands.h"
#include "output_files.h"
#include "strut/daq/session.h"
#include "strut/report/fit_report.h"
#include "strut/report/html_report.h"
#include "strut/sim/drop_prediction.h"
#include "strut/sim/recorded_truth.h"
#include "option_checks.h"

namespace strut::tools {
namespace {

nlohmann::json Number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

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

nlohmann::json FiguresJson(const sim::DropFigures& figures, const sim::DropPrediction* prediction) {
  nlohmann::json j;
  const std::vector<double> values = sim::FigureValues(figures);
  for (std::size_t f = 0; f < values.size(); ++f) j[sim::DropFigureNames()[f].name] = Number(values[f]);
  if (prediction && !prediction->uncertainty.empty()) {
    for (std::size_t f = 0; f < values.size(); ++f) {
      const sim::FigureUncertainty& u = prediction->uncertainty[f];
      j["intervals"][sim::DropFigureNames()[f].name] = {
          {"sd", Number(u.sd)}, {"lower", Number(u.lower)}, {"upper", Number(u.upper)}};
    }
    j["interval_parameters"] = prediction->interval_parameters;
    j["interval_notes"] = prediction->interval_notes;
  }
  return j;
}

//! Every `step`-th sample (at most ~4000 per trace in a plot), over t <= t_max.
report::Series Trace(const std::string& name, const std::vector<double>& t, const std::vector<double>& y, double scale,
                    double t_max) {
  report::Series s;
  s.name = name;
  std::size_t end = 0;
  while (end < t.size() && t[end] <= t_max) ++end;
  const std::size_t step = std::max<std::size_t>(1, end / 4000);
  for (std::size_t i = 0; i < end && i < y.size(); i += step) {
    s.x.push_back(t[i]);
    s.y.push_back(y[i] * scale);
  }
  return s;
}

std::string Format(double v, const char* unit) {
  if (!std::isfinite(v)) return "-";
  const std::string u = unit;
  if (u == "N") return fmt::format("{:.3f} kN", v * 1e-3);
  if (u == "m") return fmt::format("{:.2f} mm", v * 1e3);
  if (u == "Pa") return fmt::format("{:.3f} bar", v * 1e-5);
  return fmt::format("{:.3f} s", v);
}

struct PredictDropCommand {
  std::string fit_path;
  std::optional<double> mass, velocity, duration;
  std::string compare_path, experiment_label;
  std::vector<std::string> scales;
  std::string json_path, report_path;
  sim::DropPredictionOptions options;
  bool no_intervals = false;

  void Run() {
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
      for (const daq::Experiment& e : session->experiments) {
        if (!experiment_label.empty() ? e.label == experiment_label : e.kind == daq::ExperimentKind::kDrop) {
          if (recorded && experiment_label.empty())
            throw std::invalid_argument(fmt::format("--compare {}: several drop experiments ('{}', '{}'); choose one "
                                                    "with --experiment",
                                                    compare_path, recorded->label, e.label));
          recorded = &e;
        }
      }
      if (!recorded)
        throw std::invalid_argument(experiment_label.empty()
                                        ? fmt::format("--compare {}: no drop experiment in the session", compare_path)
                                        : fmt::format("--compare {}: no experiment '{}'", compare_path, experiment_label));
      if (recorded->kind != daq::ExperimentKind::kDrop)
        throw std::invalid_argument(
            fmt::format("--compare {}: experiment '{}' is not a drop", compare_path, recorded->label));
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

    // What-if scaling multiplies a value and, with it, its sd (the covariance's row and column).
    std::vector<double> theta = fit.parameters.values();
    Eigen::MatrixXd covariance = fit.covariance;
    for (const auto& [position, factor] : scale) {
      theta[position] *= factor;
      const auto it = std::find(fit.estimated_positions.begin(), fit.estimated_positions.end(), position);
      if (it != fit.estimated_positions.end()) {
        const Eigen::Index a = it - fit.estimated_positions.begin();
        covariance.row(a) *= factor;
        covariance.col(a) *= factor;
      }
    }
    spdlog::info("predicting a drop of {} kg at {} m/s for {} s with {} from {}", *mass, *velocity, options.duration,
                 fit.model.composition(), fit_path);
    const sim::DropPrediction predicted =
        sim::PredictDrop(fit.model, theta, *mass, *velocity, fit.estimated_positions, covariance, options);
    std::optional<sim::DropPrediction> fitted;  // the fit as it is, when scaled
    if (!scale.empty()) {
      sim::DropPredictionOptions plain = options;
      plain.intervals = false;
      fitted = sim::PredictDrop(fit.model, fit.parameters.values(), *mass, *velocity, {}, Eigen::MatrixXd(), plain);
    }
    for (const std::string& note : predicted.interval_notes) spdlog::info("intervals: {}", note);

    std::optional<sim::DropTrace> measured_trace;
    std::optional<sim::DropFigures> measured;
    if (recorded) {
      const int offset = fit.parameters.position_of_index(12);
      measured_trace = sim::DropTraceFromRecord(*recorded, offset >= 0 ? fit.parameters.value(offset) : 0.0);
      // The record has no model: its settling is measured against the predicted static stroke.
      measured = sim::MeasureDrop(*measured_trace, predicted.figures.static_stroke, options.settle_band);
      measured->static_stroke = NAN;
    }
    std::vector<sim::MissingPhysics> missing;
    if (session) {
      if (const auto truth = sim::ReadRecordedTruth(*session))
        missing = sim::AttributeMissingPhysics(truth->composition, truth->parameters, fit.model, *mass, *velocity, options);
    }

    // The table.
    const auto& names = sim::DropFigureNames();
    const std::vector<double> p = sim::FigureValues(predicted.figures);
    const std::vector<double> m = measured ? sim::FigureValues(*measured) : std::vector<double>(p.size(), NAN);
    std::vector<std::vector<std::string>> rows;
    nlohmann::json errors = nlohmann::json::object(), inside = nlohmann::json::object();
    for (std::size_t f = 0; f < p.size(); ++f) {
      std::vector<std::string> row{names[f].name, Format(p[f], names[f].unit)};
      const sim::FigureUncertainty u = predicted.uncertainty.empty() ? sim::FigureUncertainty{} : predicted.uncertainty[f];
      row.push_back(std::isfinite(u.sd) ? Format(u.lower, names[f].unit) + " .. " + Format(u.upper, names[f].unit) : "-");
      if (fitted) row.push_back(Format(sim::FigureValues(fitted->figures)[f], names[f].unit));
      if (measured) {
        row.push_back(Format(m[f], names[f].unit));
        const double error = (p[f] - m[f]) / std::abs(m[f]);
        row.push_back(std::isfinite(error) ? fmt::format("{:+.1f} %", 100 * error) : "-");
        errors[names[f].name] = Number(error);
        if (std::isfinite(u.sd) && std::isfinite(m[f])) inside[names[f].name] = m[f] >= u.lower && m[f] <= u.upper;
      }
      rows.push_back(row);
    }
    std::vector<std::string> header{"figure", "predicted", fmt::format("{:.0f} % interval", 100 * options.level)};
    if (fitted) header.push_back("fit unscaled");
    if (measured) header.insert(header.end(), {"measured", "error"});
    for (std::size_t c = 0; c < header.size(); ++c) std::cout << fmt::format("{:<22}", header[c]);
    std::cout << "\n";
    for (const auto& row : rows) {
      for (const auto& cell : row) std::cout << fmt::format("{:<22}", cell);
      std::cout << "\n";
    }
    for (const sim::MissingPhysics& x : missing)
      std::cout << fmt::format("the truth has {}, the fitted model not: {}\n", x.term, x.affects);
    std::cout << fmt::format("{} transient run(s), the prediction itself {:.3f} s ({} IDA steps), all {:.3f} s\n",
                             predicted.simulations, predicted.nominal_seconds, predicted.ida_steps, predicted.seconds);

    if (!json_path.empty()) {
      nlohmann::json j;
      j["fit"] = fit_path;
      j["model"] = fit.model.composition();
      j["fit_verdict"] = fit.verdict;
      j["mass"] = *mass;
      j["impact_velocity"] = *velocity;
      j["duration"] = options.duration;
      j["scale"] = nlohmann::json::object();
      for (const auto& [position, factor] : scale) j["scale"][fit.parameters.spec(position).key()] = factor;
      j["uncertainty"] = {{"method", "linearisation: each figure's gradient by central differences over +-1 sd of each "
                                     "estimated parameter, sd^2 = g' C g with the fit's posterior covariance C"},
                          {"level", options.level}};
      j["predicted"] = FiguresJson(predicted.figures, &predicted);
      if (fitted) j["fitted"] = FiguresJson(fitted->figures, nullptr);
      if (measured) {
        j["measured"] = FiguresJson(*measured, nullptr);
        j["measured"]["session"] = compare_path;
        j["measured"]["experiment"] = recorded->label;
        j["relative_error"] = errors;
        j["measured_inside_interval"] = inside;
      }
      j["missing_physics"] = nlohmann::json::array();
      for (const sim::MissingPhysics& x : missing) {
        nlohmann::json changes = nlohmann::json::object();
        for (std::size_t f = 0; f < x.relative_change.size(); ++f) changes[names[f].name] = Number(x.relative_change[f]);
        j["missing_physics"].push_back({{"term", x.term}, {"affects", x.affects}, {"relative_change", changes}});
      }
      j["timing"] = {{"simulations", predicted.simulations},
                     {"prediction_seconds", predicted.nominal_seconds},
                     {"total_seconds", predicted.seconds},
                     {"ida_steps", predicted.ida_steps}};
      WriteTextOutput(json_path, j.dump(1) + "\n");
    }
    if (!report_path.empty()) {
      report::HtmlReport report(fmt::format("strut predict drop: {} kg at {} m/s", *mass, *velocity));
      report.AddParagraph(fmt::format(
          "Model {} fitted in {} (verdict {}), integrated in mass-load mode for {} s. Intervals: {:.0f} %, by "
          "linearisation (central differences over +-1 sd of each estimated parameter, the fit's covariance).{}",
          fit.model.composition(), fit_path, fit.verdict, options.duration, 100 * options.level,
          scale.empty() ? "" : " What-if scaling applied to the prediction; 'fit unscaled' is the fit as it is."));
      report.AddTable(header, rows, "Figures of the drop (docs/drop-prediction.md)");
      if (!missing.empty()) {
        std::vector<std::vector<std::string>> mrows;
        for (const auto& x : missing) mrows.push_back({x.term, x.affects});
        report.AddTable({"physics the truth has, the fitted model not", "figures it affects"}, mrows);
      }
      const double impact = std::min(2.5, options.duration);
      const auto plot = [&](const std::string& title, double t_max, const std::string& y_label,
                            std::vector<double> sim::DropTrace::*channel, double factor) {
        std::vector<report::Series> series;
        if (!(predicted.trace.*channel).empty())
          series.push_back(Trace("predicted", predicted.trace.time, predicted.trace.*channel, factor, t_max));
        if (fitted && !(fitted->trace.*channel).empty())
          series.push_back(Trace("fit unscaled", fitted->trace.time, fitted->trace.*channel, factor, t_max));
        if (measured_trace && !((*measured_trace).*channel).empty())
          series.push_back(Trace("measured", measured_trace->time, (*measured_trace).*channel, factor, t_max));
        if (!series.empty()) report.AddLinePlot(title, "time from contact (s)", y_label, series);
      };
      plot("Stroke, impact", impact, "stroke (mm)", &sim::DropTrace::stroke, 1e3);
      plot("Axle force, impact", impact, "force (kN)", &sim::DropTrace::force, 1e-3);
      plot("Gas pressure, impact", impact, "absolute pressure (bar)", &sim::DropTrace::pressure, 1e-5);
      plot("Stroke, whole record (the gas cooling)", options.duration, "stroke (mm)", &sim::DropTrace::stroke, 1e3);
      if (!predicted.interval_notes.empty()) {
        std::string notes;
        for (const auto& n : predicted.interval_notes) notes += n + "\n";
        report.AddParagraph("Left out of the intervals:\n" + notes);
      }
      report.Write(report_path);
      spdlog::info("wrote {}", report_path);
    }
  }
};

}  // namespace

void RegisterPredictCommand(CLI::App& app) {
  CLI::App* predict = app.add_subcommand("predict", "Predictions from an identified model");
  predict->require_subcommand(1);
  auto command = std::make_shared<PredictDropCommand>();
  CLI::App* sub = predict->add_subcommand(
      "drop", "Drop test predicted from a fit (strut identify --json): figures with intervals, optionally compared "
              "with a recorded drop (docs/drop-prediction.md)");
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
  sub->add_flag("--no-intervals", command->no_intervals, "Skip the intervals (one transient run instead of 1 + 2 per parameter).");
  sub->callback([command] { command->Run(); });
}

}  // namespace strut::tools
