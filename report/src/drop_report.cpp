// The drop prediction's table, JSON record and HTML report (drop_report.h).
#include "strut/report/drop_report.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "strut/report/fit_report.h"
#include "strut/report/html_report.h"

namespace strut::report {
namespace {

nlohmann::json Number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

//! A figure in the reports' unit: mm to 0.01, kN to 0.001, MPa to 0.0001, s to 0.001.
std::string FigureText(double v, const std::string& si_unit) {
  if (!std::isfinite(v)) return "-";
  const DisplayUnit d = DisplayUnitOf(si_unit);
  const int decimals = si_unit == "m" ? 2 : si_unit == "Pa" ? 4 : 3;
  return fmt::format("{:.{}f} {}", d.Value(v), decimals, d.unit);
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

//! Every `step`-th sample (at most ~4000 per trace in a plot), over t <= t_max, in `unit`.
Series Trace(const std::string& name, const std::vector<double>& t, const std::vector<double>& y,
             const DisplayUnit& unit, double t_max) {
  Series s;
  s.name = name;
  std::size_t end = 0;
  while (end < t.size() && t[end] <= t_max) ++end;
  const std::size_t step = std::max<std::size_t>(1, end / 4000);
  for (std::size_t i = 0; i < end && i < y.size(); i += step) {
    s.x.push_back(t[i]);
    s.y.push_back(unit.Value(y[i]));
  }
  return s;
}

sim::FigureUncertainty Uncertainty(const sim::DropPrediction& p, std::size_t f) {
  return p.uncertainty.empty() ? sim::FigureUncertainty{} : p.uncertainty[f];
}

}  // namespace

DropTable DropFigureTable(const DropComparison& drop) {
  const auto& names = sim::DropFigureNames();
  const sim::DropPrediction& predicted = drop.prediction.predicted;
  const std::vector<double> p = sim::FigureValues(predicted.figures);
  const std::vector<double> m =
      drop.measured ? sim::FigureValues(drop.measured->figures) : std::vector<double>(p.size(), NAN);
  DropTable t;
  t.header = {"figure", "predicted", fmt::format("{:.0f} % interval", 100 * drop.options.level)};
  if (drop.prediction.unscaled) t.header.push_back("fit unscaled");
  if (drop.measured) t.header.insert(t.header.end(), {"measured", "error"});
  for (std::size_t f = 0; f < p.size(); ++f) {
    const std::string unit = names[f].unit;
    std::vector<std::string> row{names[f].name, FigureText(p[f], unit)};
    const sim::FigureUncertainty u = Uncertainty(predicted, f);
    row.push_back(std::isfinite(u.sd) ? FigureText(u.lower, unit) + " .. " + FigureText(u.upper, unit) : "-");
    if (drop.prediction.unscaled) row.push_back(FigureText(sim::FigureValues(drop.prediction.unscaled->figures)[f], unit));
    if (drop.measured) {
      row.push_back(FigureText(m[f], unit));
      const double error = (p[f] - m[f]) / std::abs(m[f]);
      row.push_back(std::isfinite(error) ? fmt::format("{:+.1f} %", 100 * error) : "-");
    }
    t.rows.push_back(row);
  }
  return t;
}

nlohmann::json DropJson(const DropComparison& drop) {
  const auto& names = sim::DropFigureNames();
  const sim::DropPrediction& predicted = drop.prediction.predicted;
  nlohmann::json j;
  j["fit"] = drop.fit_path;
  j["model"] = drop.model;
  j["fit_verdict"] = drop.fit_verdict;
  j["mass"] = drop.mass;
  j["impact_velocity"] = drop.impact_velocity;
  j["duration"] = drop.options.duration;
  j["moving_mass"] = std::string(sim::ToString(drop.options.moving_mass));
  j["scale"] = nlohmann::json::object();
  for (const auto& [key, factor] : drop.scale) j["scale"][key] = factor;
  j["uncertainty"] = {{"method", "linearisation: each figure's gradient by central differences over +-1 sd of each "
                                 "estimated parameter, sd^2 = g' C g with the fit's posterior covariance C"},
                      {"level", drop.options.level}};
  j["predicted"] = FiguresJson(predicted.figures, &predicted);
  if (drop.prediction.unscaled) j["fitted"] = FiguresJson(drop.prediction.unscaled->figures, nullptr);
  if (drop.measured) {
    const std::vector<double> p = sim::FigureValues(predicted.figures);
    const std::vector<double> m = sim::FigureValues(drop.measured->figures);
    nlohmann::json errors = nlohmann::json::object(), inside = nlohmann::json::object();
    for (std::size_t f = 0; f < p.size(); ++f) {
      errors[names[f].name] = Number((p[f] - m[f]) / std::abs(m[f]));
      const sim::FigureUncertainty u = Uncertainty(predicted, f);
      if (std::isfinite(u.sd) && std::isfinite(m[f])) inside[names[f].name] = m[f] >= u.lower && m[f] <= u.upper;
    }
    j["measured"] = FiguresJson(drop.measured->figures, nullptr);
    j["measured"]["session"] = drop.measured_session;
    j["measured"]["experiment"] = drop.measured_experiment;
    j["relative_error"] = errors;
    j["measured_inside_interval"] = inside;
  }
  j["missing_physics"] = nlohmann::json::array();
  for (const sim::MissingPhysics& x : drop.missing) {
    nlohmann::json changes = nlohmann::json::object();
    for (std::size_t f = 0; f < x.relative_change.size(); ++f) changes[names[f].name] = Number(x.relative_change[f]);
    j["missing_physics"].push_back({{"term", x.term}, {"affects", x.affects}, {"relative_change", changes}});
  }
  j["timing"] = {{"simulations", predicted.simulations},
                 {"prediction_seconds", predicted.nominal_seconds},
                 {"total_seconds", predicted.seconds},
                 {"ida_steps", predicted.ida_steps}};
  return j;
}

void WriteDropReport(const DropComparison& drop, const std::string& path) {
  const sim::DropPrediction& predicted = drop.prediction.predicted;
  const sim::DropPredictionOptions& options = drop.options;
  HtmlReport report(fmt::format("strut predict drop: {} kg at {} m/s", drop.mass, drop.impact_velocity));
  report.AddParagraph(fmt::format(
      "Model {} fitted in {} (verdict {}), integrated in mass-load mode for {} s; moving mass: {}. Intervals: {:.0f} %, by "
      "linearisation (central differences over +-1 sd of each estimated parameter, the fit's covariance).{}",
      drop.model, drop.fit_path, drop.fit_verdict, options.duration,
      options.moving_mass == sim::DropMovingMass::kDroppedAlone ? "the dropped mass alone (theta1 stays on the ground)"
                                                                 : "the dropped mass carrying theta1",
      100 * options.level,
      drop.scale.empty() ? "" : " What-if scaling applied to the prediction; 'fit unscaled' is the fit as it is."));
  const DropTable table = DropFigureTable(drop);
  report.AddTable(table.header, table.rows, "Figures of the drop (docs/drop-prediction.md)");
  if (!drop.missing.empty()) {
    std::vector<std::vector<std::string>> rows;
    for (const auto& x : drop.missing) rows.push_back({x.term, x.affects});
    report.AddTable({"physics the truth has, the fitted model not", "figures it affects"}, rows);
  }
  const double impact = std::min(2.5, options.duration);
  const auto plot = [&](const std::string& title, double t_max, const std::string& quantity, const std::string& channel,
                        std::vector<double> sim::DropTrace::*values) {
    const DisplayUnit unit = ChannelDisplayUnit(channel);
    std::vector<Series> series;
    if (!(predicted.trace.*values).empty())
      series.push_back(Trace("predicted", predicted.trace.time, predicted.trace.*values, unit, t_max));
    const std::optional<sim::DropPrediction>& unscaled = drop.prediction.unscaled;
    if (unscaled && !(unscaled->trace.*values).empty())
      series.push_back(Trace("fit unscaled", unscaled->trace.time, unscaled->trace.*values, unit, t_max));
    if (drop.measured && !(drop.measured->trace.*values).empty())
      series.push_back(Trace("measured", drop.measured->trace.time, drop.measured->trace.*values, unit, t_max));
    if (!series.empty())
      report.AddLinePlot(title, AxisLabel("time from contact", DisplayUnitOf("s")), AxisLabel(quantity, unit), series);
  };
  plot("Stroke, impact", impact, "stroke", "stroke", &sim::DropTrace::stroke);
  plot("Axle force, impact", impact, "force", "force", &sim::DropTrace::force);
  plot("Gas pressure, impact", impact, "absolute pressure", "pressure", &sim::DropTrace::pressure);
  plot("Stroke, whole record (the gas cooling)", options.duration, "stroke", "stroke", &sim::DropTrace::stroke);
  if (!predicted.interval_notes.empty()) {
    std::string notes;
    for (const auto& n : predicted.interval_notes) notes += n + "\n";
    report.AddParagraph("Left out of the intervals:\n" + notes);
  }
  report.Write(path);
}

}  // namespace strut::report
