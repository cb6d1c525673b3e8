#include <fmt/format.h>

#include <cmath>

#include "strut/ident/fit_report.h"
#include "strut/ident/html_report.h"

namespace strut::ident {
namespace {

std::vector<double> Times(const std::vector<double>& phases, double frequency) {
  std::vector<double> t(phases.size());
  for (std::size_t i = 0; i < phases.size(); ++i) t[i] = phases[i] / frequency;
  return t;
}

std::vector<double> Values(const Eigen::VectorXd& v, double scale = 1.0) {
  std::vector<double> out(v.size());
  for (Eigen::Index i = 0; i < v.size(); ++i) out[i] = v[i] * scale;
  return out;
}

// Display units: mm, kN, MPa, degrees C read better than SI in plots.
struct Display {
  double scale, offset;
  std::string unit;
};
Display DisplayOf(const std::string& channel) {
  if (channel == "stroke") return {1e3, 0.0, "mm"};
  if (channel == "force") return {1e-3, 0.0, "kN"};
  if (channel == "pressure") return {1e-6, 0.0, "MPa"};
  if (channel == "temperature") return {1.0, -273.15, "°C"};
  return {1.0, 0.0, "SI"};
}

}  // namespace

void WriteFitReport(const FitSummary& fit, const std::string& path, const std::string& title) {
  HtmlReport report(title);
  report.AddHeading("Summary");
  report.AddParagraph(fit.VerdictText());
  report.AddParagraph(fmt::format("Model {}: {} after {} iterations. Log-likelihood {:.6g}, AIC {:.6g}, BIC {:.6g}, "
                                  "{} residuals over {} experiments.",
                                  fit.model, fit.converged ? "converged" : "NOT converged", fit.iterations, fit.loglik,
                                  fit.aic, fit.bic, fit.observations, fit.experiments.size()));
  if (!fit.warnings.empty()) {
    std::string text = "Warnings:";
    for (const auto& w : fit.warnings) text += "\n• " + w;
    report.AddParagraph(text);
  }

  report.AddHeading("Parameters");
  std::vector<std::vector<std::string>> rows;
  for (int i = 0; i < fit.parameters.size(); ++i) {
    const ParameterSpec& s = fit.parameters.spec(i);
    const double v = fit.parameters.value(i), sd = fit.sd[i];
    rows.push_back({s.key(), s.name, fmt::format("{:.6g}", v), s.unit,
                    fit.estimated[i] ? fmt::format("{:.3g}", sd) : "",
                    fit.estimated[i] ? fmt::format("[{:.6g}, {:.6g}]", v - 1.96 * sd, v + 1.96 * sd) : "",
                    fit.estimated[i] ? "estimated" : "fixed"});
  }
  report.AddTable({"index", "name", "value", "unit", "sd", "95 % interval", ""}, rows);

  report.AddHeading("Channels");
  rows.clear();
  for (const FitChannel& c : fit.channels)
    rows.push_back({c.name, fmt::format("{:.4g}", c.rms), fmt::format("{:.4g}", c.variance),
                    fmt::format("{:.4g}", c.noise_floor_variance),
                    fmt::format("{:.3g}", c.noise_ratio)});
  report.AddTable({"channel", "residual rms (SI)", "variance v_b", "noise floor variance", "noise ratio"}, rows,
                  "A ratio near 1 means the model explains all the data can show; far above 1, physics is missing.");

  // Residual mean and 2 sigma per experiment (paper Figs. 8 and 11), one plot per channel.
  std::vector<std::string> labels;
  for (const auto& e : fit.experiments) labels.push_back(e.label);
  report.AddHeading("Residuals per experiment");
  for (std::size_t c = 0; c < fit.channels.size(); ++c) {
    const Display d = DisplayOf(fit.channels[c].name);
    ErrorBarSeries series{fit.channels[c].name, {}, {}};
    for (const auto& e : fit.experiments) {
      series.mean.push_back(e.converged ? e.channels[c].mean * d.scale : NAN);
      series.sigma.push_back(e.converged ? e.channels[c].sd * d.scale : NAN);
    }
    report.AddErrorBars(fmt::format("{} residual: mean ± 2σ per experiment", fit.channels[c].name),
                        fmt::format("{} [{}]", fit.channels[c].name, d.unit), labels, {series});
  }
  rows.clear();
  for (const auto& e : fit.experiments) {
    std::vector<std::string> row{e.label, e.group, fmt::format("{:.2f}", e.frequency),
                                 fmt::format("{:.0f}", e.static_position * 1e3), fmt::format("{:.0f}", e.amplitude * 1e3)};
    for (const auto& c : e.channels) row.push_back(e.converged ? fmt::format("{:.3g}", c.noise_ratio) : "—");
    rows.push_back(row);
  }
  std::vector<std::string> header{"experiment", "group", "Hz", "static mm", "amplitude mm"};
  for (const auto& c : fit.channels) header.push_back(c.name + " noise ratio");
  report.AddTable(header, rows);

  if (fit.correlation.rows() > 0) {
    report.AddHeading("Correlation of the estimates");
    std::vector<std::string> names;
    for (int i : fit.estimated_positions) names.push_back(fit.parameters.spec(i).key());
    report.AddHeatmap("correlation", names, fit.correlation, -1.0, 1.0);
  }

  report.AddHeading("Convergence");
  Series history{"log-likelihood", {}, {}, "lines+markers"};
  for (const auto& h : fit.history) {
    history.x.push_back(h.iteration);
    history.y.push_back(h.objective);
  }
  report.AddLinePlot("log-likelihood per iteration", "iteration", "log-likelihood", {history});

  report.AddHeading("Measured and predicted, per experiment");
  for (const auto& e : fit.experiments) {
    report.AddHeading(fmt::format("Experiment {} ({}, {:.2f} Hz, {:.0f} ± {:.0f} mm)", e.label, e.group, e.frequency,
                                  e.static_position * 1e3, e.amplitude * 1e3),
                      3);
    if (!e.converged) {
      report.AddParagraph("No periodic solution: " + e.error);
      continue;
    }
    const std::vector<double> t_measured = Times(e.phases, e.frequency);
    const std::vector<double> t_model = e.solution.time();
    for (const auto& c : e.channels) {
      const Display d = DisplayOf(c.channel);
      const auto measured = e.measured.find(c.channel);
      std::vector<Series> series;
      if (measured != e.measured.end())
        series.push_back({"measured", t_measured, Values(measured->second.array() * d.scale + d.offset), "markers"});
      series.push_back({"predicted", t_model, Values(e.solution.channel(c.channel).array() * d.scale + d.offset)});
      report.AddLinePlot(fmt::format("{}: {}", e.label, c.channel), "time in period [s]",
                         fmt::format("{} [{}]", c.channel, d.unit), series);
    }
    for (const char* y : {"force", "pressure"}) {
      const auto ms = e.measured.find("stroke"), my = e.measured.find(y);
      std::vector<Series> series;
      if (ms != e.measured.end() && my != e.measured.end())
        series.push_back({"measured", Values(ms->second, 1e3), Values(my->second, DisplayOf(y).scale), "markers"});
      series.push_back({"predicted", Values(e.solution.channel("stroke"), 1e3),
                        Values(e.solution.channel(y), DisplayOf(y).scale)});
      report.AddLinePlot(fmt::format("{}: {}-stroke loop", e.label, y), "stroke [mm]",
                         fmt::format("{} [{}]", y, DisplayOf(y).unit), series);
    }
  }
  report.Write(path);
}

}  // namespace strut::ident
