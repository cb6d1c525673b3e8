#include "strut/report/fit_report.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "strut/report/html_report.h"

namespace strut::report {

using namespace strut::ident;
namespace {

std::vector<double> Times(const std::vector<double>& phases, double frequency) {
  std::vector<double> t(phases.size());
  for (std::size_t i = 0; i < phases.size(); ++i) t[i] = phases[i] / frequency;
  return t;
}

std::vector<double> Values(const Eigen::VectorXd& v, const DisplayUnit& d) {
  std::vector<double> out(v.size());
  for (Eigen::Index i = 0; i < v.size(); ++i) out[i] = d.Value(v[i]);
  return out;
}

// A value with its sd, both in the same display unit: "4.2005e-3 ± 1.2e-6" style.
std::string WithSd(double value, double sd) {
  if (!std::isfinite(sd)) return fmt::format("{:.6g}", value);
  return fmt::format("{:.6g} ± {:.2g}", value, sd);
}

Tone ToneOf(FitVerdict verdict) {
  switch (verdict) {
    case FitVerdict::kAtNoiseFloor: return Tone::kGood;
    case FitVerdict::kAboveNoiseFloor: return Tone::kWarning;
    case FitVerdict::kNotConverged: break;
  }
  return Tone::kBad;
}

}  // namespace

DisplayUnit DisplayUnitOf(const std::string& unit) {
  if (unit == "m") return {1e3, 0.0, "mm"};
  if (unit == "N") return {1e-3, 0.0, "kN"};
  if (unit == "Pa") return {1e-6, 0.0, "MPa"};
  return {1.0, 0.0, unit};
}

DisplayUnit ChannelDisplayUnit(const std::string& name) {
  // A transient experiment's channel ("drop:stroke") is shown like the recorded channel.
  const std::string channel = name.substr(name.find(':') == std::string::npos ? 0 : name.find(':') + 1);
  if (channel == "stroke") return DisplayUnitOf("m");
  if (channel == "force") return DisplayUnitOf("N");
  if (channel == "pressure") return DisplayUnitOf("Pa");
  if (channel == "temperature") return {1.0, -273.15, "°C"};
  return {1.0, 0.0, ""};  // a channel of a generic model (u, y): shown as recorded, no unit
}

std::string AxisLabel(const std::string& quantity, const DisplayUnit& d) {
  return d.unit.empty() ? quantity : quantity + " [" + d.unit + "]";
}

void AddVerdict(HtmlReport& report, const FitSummary& fit) { report.AddCallout(fit.VerdictText(), ToneOf(fit.Verdict())); }

void AddParameterTable(HtmlReport& report, const FitSummary& fit) {
  const bool widened = fit.WidenedForMisfit();
  std::vector<std::vector<std::string>> rows;
  for (int i = 0; i < fit.parameters.size(); ++i) {
    const ParameterSpec& s = fit.parameters.spec(i);
    const DisplayUnit d = DisplayUnitOf(s.unit);
    const double v = d.Value(fit.parameters.value(i)), sd = fit.estimates[i].sd * d.scale;
    std::vector<std::string> row{s.key(), s.name, fit.estimates[i].estimated ? WithSd(v, sd) : fmt::format("{:.6g}", v), d.unit,
                                 fit.estimates[i].estimated ? fmt::format("[{:.6g}, {:.6g}]", v - 1.96 * sd, v + 1.96 * sd) : ""};
    if (widened) {
      const double f = fit.estimates[i].misfit_sd_factor;
      row.push_back(fit.estimates[i].estimated && std::isfinite(f) ? fmt::format("× {:.2f}", f) : "");
    }
    row.push_back(fit.estimates[i].estimated ? "estimated" : "fixed");
    rows.push_back(std::move(row));
  }
  std::vector<std::string> header{"index", "name", "value ± sd", "unit", "95 % interval"};
  if (widened) header.push_back("sd widened for the misfit");
  header.push_back("");
  std::string caption = widened ? "Above the noise floor: every sd and interval is widened for the misfit (the factor "
                                  "beside it), and the estimates of a model that lacks physics are biased beyond them."
                                : "The sd is the posterior standard deviation; the interval is ± 1.96 sd.";
  if (!fit.calibration.empty()) caption += " Each sd holds the transducers' calibration (gain sd " + GainSdText(fit.calibration) + ").";
  report.AddTable(header, rows, caption);
}

void AddChannelTable(HtmlReport& report, const FitSummary& fit) {
  std::vector<std::vector<std::string>> rows;
  for (const FitChannel& c : fit.channels) {
    const DisplayUnit d = ChannelDisplayUnit(c.name);
    const std::string squared = d.unit.empty() ? "" : d.unit + "²";
    rows.push_back({c.name, fmt::format("{:.4g}", c.rms * d.scale), d.unit,
                    fmt::format("{:.4g}", c.variance * d.scale * d.scale),
                    fmt::format("{:.4g}", c.noise_floor_variance * d.scale * d.scale), squared,
                    fmt::format("{:.3g}", c.noise_ratio), fmt::format("{:.3g}", c.noise_floor_limit)});
  }
  report.AddTable({"channel", "residual rms", "unit", "residual variance v_b", "noise floor variance", "unit of variances",
                   "noise ratio", "noise alone stays below"},
                  rows,
                  fmt::format("The noise ratio is the residual over the noise variance of the averaged data, pooled "
                              "over the experiments: about 1 means the model explains all the data can show. With "
                              "the model right, noise alone puts a channel above the last column with probability "
                              "{} (the ratio's sampling distribution: the averaged samples, and the periods the "
                              "noise is estimated from); above it physics is missing.",
                              kNoiseFloorFalseAlarm));
}

void AddResidualBars(HtmlReport& report, const FitSummary& fit) {
  std::vector<std::string> labels;
  for (const auto& e : fit.experiments) labels.push_back(e.label);
  for (std::size_t c = 0; c < fit.channels.size(); ++c) {
    // The periodic experiments' channels (a drop's follow them and are plotted with the drop).
    if (fit.experiments.empty() || c >= fit.experiments.front().channels.size()) break;
    const DisplayUnit d = ChannelDisplayUnit(fit.channels[c].name);
    ErrorBarSeries series{fit.channels[c].name, {}, {}};
    for (const auto& e : fit.experiments) {
      series.mean.push_back(e.converged ? e.channels[c].mean * d.scale : NAN);
      series.sigma.push_back(e.converged ? e.channels[c].sd * d.scale : NAN);
    }
    report.AddErrorBars(fmt::format("{} residual per experiment", fit.channels[c].name),
                        AxisLabel(fit.channels[c].name + " residual", d), labels, {series});
  }
}

void AddExperimentPlots(HtmlReport& report, const FitSummary& fit) {
  for (const auto& e : fit.experiments) {
    report.AddHeading(fmt::format("Experiment {} ({}, {:.2f} Hz, {:.0f} ± {:.0f} mm)", e.label, e.group, e.frequency,
                                  e.static_position * 1e3, e.amplitude * 1e3),
                      3);
    if (!e.converged) {
      report.AddCallout("No periodic solution at the final parameters: " + e.error, Tone::kBad);
      continue;
    }
    const std::vector<double> t_measured = Times(e.phases, e.frequency);
    const std::vector<double> t_model = e.solution.time();
    const double t_end = 1.0 / e.frequency;
    for (const auto& c : e.channels) {
      const DisplayUnit d = ChannelDisplayUnit(c.channel);
      const auto measured = e.measured.find(c.channel);
      LinePlot overlay{fmt::format("{}: {}", e.label, c.channel), "time in the period [s]", AxisLabel(c.channel, d), {}};
      if (measured != e.measured.end())
        overlay.series.push_back({"measured", t_measured, Values(measured->second, d), "markers"});
      overlay.series.push_back({"predicted", t_model, Values(e.solution.channel(c.channel), d)});
      LinePlot residual{fmt::format("{}: {} residual, measured − predicted", e.label, c.channel),
                        "time in the period [s]", AxisLabel(c.channel + " residual", d), {}};
      const auto r = e.residual.find(c.channel);
      if (r != e.residual.end()) {
        std::vector<double> y(r->second.size());
        for (Eigen::Index i = 0; i < r->second.size(); ++i) y[i] = r->second[i] * d.scale;
        residual.series.push_back({"residual", t_measured, y});
      }
      const auto noise = e.noise_variance.find(c.channel);
      if (noise != e.noise_variance.end() && std::isfinite(noise->second)) {
        // The noise band of the averaged data: a residual inside it is noise.
        const double s = 2.0 * std::sqrt(noise->second) * d.scale;
        residual.series.push_back({"± 2σ noise", {0.0, t_end, 0.0, 0.0, t_end}, {s, s, NAN, -s, -s}});
      }
      report.AddLinePlots({overlay, residual});
    }
    std::vector<LinePlot> loops;
    const DisplayUnit ds = ChannelDisplayUnit("stroke");
    const auto has = [&](const char* channel) {
      return std::find(e.solution.channels.begin(), e.solution.channels.end(), channel) != e.solution.channels.end();
    };
    for (const char* y : {"force", "pressure"}) {
      if (!has("stroke") || !has(y)) continue;
      const DisplayUnit dy = ChannelDisplayUnit(y);
      const auto ms = e.measured.find("stroke"), my = e.measured.find(y);
      LinePlot loop{fmt::format("{}: {}-stroke loop", e.label, y), AxisLabel("stroke", ds), AxisLabel(y, dy), {}};
      if (ms != e.measured.end() && my != e.measured.end())
        loop.series.push_back({"measured", Values(ms->second, ds), Values(my->second, dy), "markers"});
      loop.series.push_back({"predicted", Values(e.solution.channel("stroke"), ds), Values(e.solution.channel(y), dy)});
      loops.push_back(std::move(loop));
    }
    if (!loops.empty()) report.AddLinePlots(loops);
  }
}

void AddContributionTable(HtmlReport& report, const FitSummary& fit) {
  if (fit.contributions.empty()) return;
  std::vector<std::string> header{"experiment", "kind"};
  for (int i : fit.estimated_positions) header.push_back(fit.parameters.spec(i).key());
  std::vector<std::vector<std::string>> rows;
  for (const ExperimentContribution& c : fit.contributions) {
    std::vector<std::string> row{c.label, c.kind};
    for (int i : fit.estimated_positions) {
      const double ratio = c.sd_without[i] / fit.estimates[i].sd;
      row.push_back(std::isinf(c.sd_without[i]) ? "undetermined"
                                                : fmt::format("{:.3g} ({:.0f} %)", ratio, 100 * c.information_share[i]));
    }
    rows.push_back(std::move(row));
  }
  report.AddTable(header, rows,
                  "Per experiment and parameter: the sd with the experiment left out over the sd of the fit "
                  "(linearised at the fit; 1: the others determine it alone), and in brackets its share of the "
                  "information on the parameter.");
}

void AddTransientPlots(HtmlReport& report, const FitSummary& fit) {
  for (const TransientExperimentFit& t : fit.transient_experiments) {
    report.AddHeading(fmt::format("{} {} ({:.0f} kg at {:.3g} m/s)", t.kind, t.label, t.drop_mass, t.impact_velocity), 3);
    if (!t.converged) {
      report.AddCallout("No prediction at the final parameters: " + t.error, Tone::kBad);
      continue;
    }
    // At most about 2000 points a curve: every k-th sample, the first 2.5 s (the impact) in full.
    const std::size_t n = t.time.size();
    std::vector<std::size_t> kept;
    const std::size_t stride = std::max<std::size_t>(1, n / 2000);
    for (std::size_t i = 0; i < n; ++i)
      if (t.time[i] <= 2.5 || i % stride == 0) kept.push_back(i);
    std::vector<double> time;
    for (std::size_t i : kept) time.push_back(t.time[i]);
    const auto pick = [&](const Eigen::VectorXd& v, const DisplayUnit& d) {
      std::vector<double> out;
      for (std::size_t i : kept) out.push_back(d.Value(v[static_cast<Eigen::Index>(i)]));
      return out;
    };
    for (const ChannelStatistics& c : t.channels) {
      const DisplayUnit d = ChannelDisplayUnit(c.channel);
      const Eigen::VectorXd& measured = t.measured.at(c.channel);
      const Eigen::VectorXd& predicted = t.predicted.at(c.channel);
      LinePlot overlay{fmt::format("{}: {}", t.label, c.channel), "time from contact [s]", AxisLabel(c.channel, d), {}};
      overlay.series.push_back({"measured", time, pick(measured, d), "markers"});
      overlay.series.push_back({"predicted", time, pick(predicted, d)});
      const DisplayUnit dr{d.scale, 0.0, d.unit};
      LinePlot residual{fmt::format("{}: {} residual, measured − predicted (noise ratio {:.3g})", t.label, c.channel,
                                    c.noise_ratio),
                        "time from contact [s]", AxisLabel(c.channel + " residual", d), {}};
      residual.series.push_back({"residual", time, pick(measured - predicted, dr)});
      const auto noise = t.noise_variance.find(c.channel);
      if (noise != t.noise_variance.end() && std::isfinite(noise->second)) {
        const double s = 2.0 * std::sqrt(noise->second) * d.scale, end = t.time.back();
        residual.series.push_back({"± 2σ noise", {0.0, end, 0.0, 0.0, end}, {s, s, NAN, -s, -s}});
      }
      report.AddLinePlots({overlay, residual});
    }
  }
}

void WriteFitReport(const FitSummary& fit, const std::string& path, const std::string& title) {
  HtmlReport report(title);
  AddVerdict(report, fit);
  report.AddParagraph(fmt::format(
      "Model {}: {} after {} iterations. Log-likelihood {:.6g}, AIC {:.6g}, BIC {:.6g}; {} residuals over {} "
      "experiments. Units throughout: stroke in mm, force in kN, pressure in MPa, temperature in °C; parameters in "
      "SI units except lengths (mm), forces (kN) and pressures (MPa).",
      fit.model, fit.converged ? "converged" : "NOT converged", fit.iterations, fit.loglik, fit.aic, fit.bic,
      fit.observations, fit.experiments.size()));
  if (!fit.warnings.empty()) {
    std::string text = "Warnings:";
    for (const auto& w : fit.warnings) text += "\n• " + w;
    report.AddCallout(text, Tone::kWarning);
  }

  report.AddHeading("Parameters");
  AddParameterTable(report, fit);

  report.AddHeading("Channels");
  AddChannelTable(report, fit);

  report.AddHeading("Residuals per experiment");
  AddResidualBars(report, fit);
  std::vector<std::vector<std::string>> rows;
  for (const auto& e : fit.experiments) {
    std::vector<std::string> row{e.label, e.group, fmt::format("{:.2f}", e.frequency),
                                 fmt::format("{:.0f}", e.static_position * 1e3), fmt::format("{:.0f}", e.amplitude * 1e3)};
    for (const auto& c : e.channels) row.push_back(e.converged ? fmt::format("{:.3g}", c.noise_ratio) : "—");
    rows.push_back(row);
  }
  std::vector<std::string> header{"experiment", "group", "frequency [Hz]", "static position [mm]", "amplitude [mm]"};
  if (!fit.experiments.empty())
    for (const auto& c : fit.experiments.front().channels) header.push_back(c.channel + " noise ratio");
  report.AddTable(header, rows, "Per experiment: residual over noise variance (about 1 at the noise floor).");

  if (!fit.transient_experiments.empty()) {
    std::vector<std::vector<std::string>> drops;
    for (const auto& t : fit.transient_experiments) {
      std::vector<std::string> row{t.label, t.kind, fmt::format("{:.0f}", t.drop_mass),
                                   fmt::format("{:.3g}", t.impact_velocity)};
      std::string ratios;
      for (const auto& c : t.channels) ratios += fmt::format("{}{} {:.3g}", ratios.empty() ? "" : ", ", c.channel, c.noise_ratio);
      row.push_back(t.converged ? ratios : "no prediction");
      drops.push_back(std::move(row));
    }
    report.AddTable({"experiment", "kind", "mass [kg]", "impact velocity [m/s]", "noise ratio"}, drops,
                    "Drops fitted beside the periodic experiments: residual over the record's noise variance at rest.");
  }
  if (!fit.contributions.empty()) {
    report.AddHeading("What each experiment adds");
    AddContributionTable(report, fit);
  }

  if (fit.correlation.rows() > 0) {
    report.AddHeading("Correlation of the estimates");
    std::vector<std::string> names;
    for (int i : fit.estimated_positions) names.push_back(fit.parameters.spec(i).key());
    report.AddHeatmap("correlation of the estimates", names, fit.correlation, -1.0, 1.0);
  }

  report.AddHeading("Convergence");
  Series history{"log-likelihood", {}, {}, "lines+markers"};
  for (const auto& h : fit.history) {
    history.x.push_back(h.iteration);
    history.y.push_back(h.objective);
  }
  report.AddLinePlot(fmt::format("log-likelihood after each of the {} iterations", fit.iterations),
                     "iteration (0: starting values)", "log-likelihood", {history});

  report.AddHeading("Measured and predicted, per experiment");
  report.AddParagraph(
      "Left: the measured values (dots, the average over the recorded periods) and the prediction (line) over one "
      "period. Right: the residual, measured − predicted, with the band of ± 2σ of the averaged data's noise; a "
      "residual that stays inside the band is noise, a pattern outside it is physics the model lacks.");
  AddExperimentPlots(report, fit);
  if (!fit.transient_experiments.empty()) {
    report.AddHeading("Measured and predicted, per drop");
    report.AddParagraph("The record (dots) and the prediction of the fitted model (line) from contact, with the "
                        "residual and the band of ± 2σ of the record's noise at rest.");
    AddTransientPlots(report, fit);
  }
  report.Write(path);
}

}  // namespace strut::report
