#include "strut/report/discover_report.h"

#include <fmt/format.h>

#include <cmath>

#include "strut/report/fit_report.h"
#include "strut/report/html_report.h"
#include "strut/ident/model.h"

namespace strut::report {

using namespace strut::ident;
namespace {

std::string Ratios(const std::map<std::string, double>& ratio) {
  std::string out;
  for (const auto& [channel, r] : ratio) out += fmt::format("{}{} {:.2f}", out.empty() ? "" : ", ", channel, r);
  return out;
}

std::string Number(double v, const char* format) {
  return std::isfinite(v) ? fmt::format(fmt::runtime(format), v) : std::string("—");
}

}  // namespace

std::string CompositionNote(const DiscoveryResult& r) {
  if (r.missing.empty()) return "";
  std::string chain = r.baseline.model;
  for (const auto& term : r.missing) chain += "+" + term;
  if (chain == r.final_model) return "";
  std::string canonical = r.final_model;
  try {
    canonical = Model::Build(chain, Causality::kStrokeInput).composition();
  } catch (const ModelError&) {
    // A chain the catalogue cannot build again: say only what discovery reported.
  }
  if (canonical != r.final_model) return "";
  return fmt::format(
      "{} is the model {}: terms are evaluated in catalogue order, so this composition and {} are the same "
      "equations and print as {} (docs/models.md). The parameters below are {}'s.",
      chain, r.final_model, r.final_model, r.final_model, r.final_model);
}

void WriteDiscoveryReport(const DiscoveryResult& r, const std::string& path) {
  HtmlReport report("strut discover: " + r.baseline.model + " → " + r.final_model);
  const bool at_floor = r.final_fit.Verdict() == FitVerdict::kAtNoiseFloor;
  report.AddCallout(r.conclusion, at_floor ? Tone::kGood : r.final_fit.converged ? Tone::kWarning : Tone::kBad);
  const std::string note = CompositionNote(r);
  if (!note.empty()) report.AddParagraph(note);
  report.AddParagraph(
      "ΔBIC is the BIC with the added term minus the BIC before it: negative means the term explains more than its "
      "parameters cost (a term is kept only below −10, very strong evidence). Noise ratios are the residual over the "
      "noise variance of the averaged data (about 1 at the noise floor). Units throughout: stroke in mm, force in kN, "
      "pressure in MPa.");

  report.AddHeading("What was added");
  std::vector<std::vector<std::string>> rows;
  for (const auto& s : r.steps)
    rows.push_back({s.removed ? s.term + " (taken out again)" : s.term, fmt::format("{:+.1f}", s.delta_bic), Ratios(s.noise_before), Ratios(s.noise_after),
                    Number(s.cv_before, "{:.3f}"), Number(s.cv_after, "{:.3f}"), s.evidence});
  if (rows.empty()) {
    report.AddParagraph(r.nothing_missing ? "Nothing: the baseline " + r.baseline.model +
                                                " already explains the data to the noise floor."
                                          : "Nothing: no catalogue term improved the fit enough to be kept.");
  } else {
    report.AddTable({"added term", "ΔBIC", "noise ratio before", "noise ratio after", "held-out noise ratio before",
                     "held-out noise ratio after", "evidence"},
                    rows,
                    "Each step adds the catalogue term with the most negative ΔBIC that also brings the noise ratios "
                    "down and predicts left-out experiments better.");
  }
  for (std::size_t k = 0; k < r.steps.size(); ++k) {
    if (r.steps[k].candidates.empty()) continue;  // a term taken out again: no round of candidates
    rows.clear();
    for (const auto& c : r.steps[k].candidates)
      rows.push_back({c.term, c.ok ? fmt::format("{:+.1f}", c.delta_bic) : "—", Ratios(c.noise_ratio),
                      Number(c.cv_ratio, "{:.3f}"), fmt::format("{:.1f}", c.evidence),
                      !c.ok                ? c.error
                      : c.verdict.empty() ? "not needed: a candidate with a more negative ΔBIC was kept"
                                          : c.verdict});
    report.AddTable({"candidate", "ΔBIC", "noise ratio", "held-out noise ratio", "evidence", "verdict"}, rows,
                    fmt::format("Round {}: every candidate refitted (ΔBIC negative is better).", k + 1));
  }

  if (r.discrepancy && !r.discrepancy->functions.empty()) {
    const EmpiricalDiscrepancy& d = *r.discrepancy;
    report.AddHeading("Empirical discrepancy (not a catalogue term)");
    std::string words;
    for (const auto& line : d.dependence) words += (words.empty() ? "" : "; ") + line;
    report.AddParagraph("What no catalogue term explains is modelled by functions of the model's own stroke, rate, "
                        "pressure and recording time, fitted with the physical parameters. It is empirical: it says "
                        "what the missing force depends on, not which physics it is. " +
                        (words.empty() ? std::string() : "It depends on the data this way: " + words + ".") +
                        (d.resembles.empty() ? std::string()
                                             : " Its shape resembles the signature of: " + [&] {
                                                 std::string t;
                                                 for (const auto& term : d.resembles) t += (t.empty() ? "" : ", ") + term;
                                                 return t;
                                               }() + "."));
    rows.clear();
    for (const auto& f : d.functions)
      rows.push_back({"theta" + std::to_string(f.index), f.name, Number(f.value, "{:.4g}"), Number(f.sd, "{:.2g}"),
                      f.shape, f.resembles.empty() ? "—" : f.resembles});
    report.AddTable({"parameter", "function", "coefficient", "sd", "shape", "resembles"}, rows,
                    "The discrepancy's functions discovery selected, in the order it added them (coefficients are "
                    "dimensionless: 1 is as large as the model level each is scaled by).");
    std::vector<LinePlot> plots;
    for (const auto& c : d.curves) {
      Series line{"missing force", c.x, {}};
      for (double f : c.force) line.y.push_back(f * 1e-3);
      plots.push_back({c.label, c.label.find("rate") != std::string::npos ? "stroke rate (m/s)" : "stroke (m)",
                       "missing force (kN)", {line}});
    }
    if (!plots.empty())
      report.AddLinePlots(plots, "The missing force the discrepancy models: against the stroke rate at the middle "
                                 "static position (negative rates: extension), and against the stroke in compression "
                                 "and in extension at the matrix's median peak rate.");
  }

  if (!r.ambiguities.empty()) {
    report.AddHeading("Explanations the data cannot tell apart");
    report.AddParagraph("A rival explains the data alike when the final model with the rival in the kept term's place "
                        "has a BIC within the margin of the final model's, or when the two terms fitted together have "
                        "sizes so correlated that the data move one into the other. Discovery kept one of them; the "
                        "data do not decide, the test below does (docs/discovery.md).");
    for (const auto& a : r.ambiguities) {
      rows.clear();
      rows.push_back({a.kept + " (kept)", r.final_model, "0", Ratios(PooledNoiseRatio(r.final_fit)), "—", "—"});
      for (const auto& rival : a.rivals)
        rows.push_back({rival.term, rival.model, Number(rival.delta_bic, "{:+.1f}"), Ratios(rival.noise_ratio),
                        Number(rival.correlation, "{:+.3f}"), rival.why});
      report.AddTable({"term", "model", "ΔBIC against the final model", "noise ratio", "sizes' correlation together",
                       "why alike"},
                      rows, "Step " + std::to_string(a.step + 1) + ": " + a.kept + " and its rivals.");
      if (a.test) report.AddParagraph("The test that decides: " + a.test->Describe() + ".");
    }
    if (r.decision) {
      report.AddHeading("The decision");
      report.AddCallout(r.decision->conclusion, r.decision->winner >= 0 ? Tone::kGood : Tone::kWarning);
    }
  }

  report.AddHeading("Where the baseline did not fit");
  rows.clear();
  for (const auto& f : r.mismatch) rows.push_back({f.locus, f.channel, fmt::format("{:.1f}", f.score), f.detail});
  if (rows.empty()) {
    report.AddParagraph("No feature of the baseline's residuals stands above the noise.");
  } else {
    report.AddTable({"feature", "channel", "score", "detail"}, rows,
                    "Scores are signed signal-to-noise ratios of each feature in the baseline's residuals: large "
                    "and positive, the feature is there; about 1 or below, it is not (negative: the residuals are "
                    "smaller there than elsewhere).");
  }
  if (!r.unexplained.empty()) {
    rows.clear();
    for (const auto& f : r.unexplained) rows.push_back({f.locus, f.channel, fmt::format("{:.1f}", f.score), f.detail});
    report.AddTable({"feature", "channel", "score", "detail"}, rows,
                    "Left unexplained by the final model " + r.final_model + " (signed signal-to-noise, as above).");
  }

  report.AddHeading("Residuals before and after");
  for (const auto& channel : r.baseline.channels) {
    const DisplayUnit d = ChannelDisplayUnit(channel.name);
    std::vector<std::string> labels;
    ErrorBarSeries before{"baseline " + r.baseline.model, {}, {}}, after{"final " + r.final_model, {}, {}};
    for (std::size_t a = 0; a < r.baseline.experiments.size(); ++a) {
      labels.push_back(r.baseline.experiments[a].label);
      for (auto* series : {&before, &after}) {
        const FitSummary& fit = series == &before ? r.baseline : r.final_fit;
        double mean = NAN, sd = NAN;
        if (a < fit.experiments.size() && fit.experiments[a].converged)
          for (const auto& c : fit.experiments[a].channels)
            if (c.channel == channel.name) mean = c.mean * d.scale, sd = c.sd * d.scale;
        series->mean.push_back(mean);
        series->sigma.push_back(sd);
      }
    }
    report.AddErrorBars(channel.name + " residual per experiment, before and after",
                        AxisLabel(channel.name + " residual", d), labels, {before, after});
  }

  report.AddHeading("The final model " + r.final_model);
  AddVerdict(report, r.final_fit);
  AddParameterTable(report, r.final_fit);
  AddChannelTable(report, r.final_fit);
  report.AddHeading("Measured and predicted by " + r.final_model + ", per experiment");
  report.AddParagraph(
      "Left: the measured values (dots) and the final model's prediction (line) over one period. Right: the "
      "residual, measured − predicted, with the band of ± 2σ of the averaged data's noise.");
  AddExperimentPlots(report, r.final_fit);
  report.Write(path);
}

}  // namespace strut::report
