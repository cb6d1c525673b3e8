#include "strut/report/qc_report.h"

#include <fmt/format.h>

#include <cmath>

#include "strut/report/html_report.h"

namespace strut::report {

using namespace strut::ident;

nlohmann::json QcToJson(const qc::Decision& d) {
  const auto number = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); };
  nlohmann::json j{{"verdict", qc::ToString(d.verdict)},
                   {"reasons", d.reasons},
                   {"serial", d.serial},
                   {"session", d.session},
                   {"reference", d.reference},
                   {"reference_kind", d.reference_kind},
                   {"model", d.model},
                   {"fit_verdict", d.fit_verdict},
                   {"fit_verdict_text", d.fit_verdict_text},
                   {"guard_band_sigmas", qc::kGuardBandSigmas},
                   {"data_issues", d.data_issues},
                   {"seconds", d.seconds},
                   {"quantities", nlohmann::json::array()}};
  for (const qc::QuantityDecision& q : d.quantities)
    j["quantities"].push_back({{"name", q.quantity.name},
                               {"unit", q.quantity.unit},
                               {"value", number(q.quantity.value)},
                               {"sd", number(q.quantity.sd)},
                               {"nominal", number(q.nominal)},
                               {"lower", number(q.lower)},
                               {"upper", number(q.upper)},
                               {"status", qc::ToString(q.status)},
                               {"meaning", q.meaning}});
  return j;
}

void WriteQcReport(const qc::Decision& d, const ident::SessionFit* fit, const std::string& path) {
  HtmlReport report(fmt::format("strut qc: {} {}", d.serial.empty() ? d.session : d.serial, qc::ToString(d.verdict)));
  report.AddHeading("Verdict");
  std::string text = fmt::format("{} for serial {} (session {}), against {} ({}); model {}, fit {}.", qc::ToString(d.verdict),
                                 d.serial.empty() ? "?" : d.serial, d.session, d.reference, d.reference_kind, d.model,
                                 d.fit_verdict.empty() ? "none" : d.fit_verdict);
  for (const auto& r : d.reasons) text += "\n• " + r;
  report.AddParagraph(text);
  report.AddParagraph(fmt::format(
      "Guard band: a quantity conforms when its 95 % interval (value ± {} sd) lies inside its band, is out when the "
      "interval lies entirely outside, and an interval that straddles a limit is decided as out (conformance not "
      "shown). A fit that did not converge or is above the noise floor, or data defects, make the verdict UNDECIDED.",
      qc::kGuardBandSigmas));
  report.AddHeading("Quantities");
  std::vector<std::vector<std::string>> rows;
  std::vector<std::string> names;
  ErrorBarSeries bars{"value (±2 sd), 0 = lower limit, 1 = upper limit", {}, {}};
  for (const qc::QuantityDecision& q : d.quantities) {
    rows.push_back({q.quantity.name, fmt::format("{:.5g}", q.quantity.value), fmt::format("{:.3g}", q.quantity.sd),
                    q.quantity.unit, fmt::format("{:.5g}", q.nominal), fmt::format("{:.5g}", q.lower),
                    fmt::format("{:.5g}", q.upper), qc::ToString(q.status), q.meaning});
    if (std::isfinite(q.lower) && std::isfinite(q.upper) && q.upper > q.lower) {
      names.push_back(q.quantity.name);
      bars.mean.push_back((q.quantity.value - q.lower) / (q.upper - q.lower));
      bars.sigma.push_back(std::isfinite(q.quantity.sd) ? q.quantity.sd / (q.upper - q.lower) : 0.0);
    }
  }
  report.AddTable({"quantity", "value", "sd", "unit", "nominal", "lower", "upper", "status", "meaning"}, rows);
  if (!names.empty())
    report.AddErrorBars("Quantities within their bands (0: lower limit, 1: upper limit)", "position in the band", names,
                        {bars}, qc::kGuardBandSigmas);
  if (!d.data_issues.empty()) {
    std::string issues = "Data defects:";
    for (const auto& i : d.data_issues) issues += "\n• " + i;
    report.AddParagraph(issues);
  }
  if (fit) {
    report.AddHeading("Fit");
    report.AddParagraph(fit->summary.VerdictText());
    std::vector<std::vector<std::string>> p;
    for (int i = 0; i < fit->summary.parameters.size(); ++i) {
      const auto& s = fit->summary.parameters.spec(i);
      p.push_back({s.key(), s.name, fmt::format("{:.6g}", fit->summary.parameters.value(i)), s.unit,
                   fit->summary.estimates[i].estimated ? fmt::format("{:.3g}", fit->summary.estimates[i].sd) : "fixed"});
    }
    report.AddTable({"index", "name", "value", "unit", "sd"}, p);
    std::vector<std::vector<std::string>> c;
    for (const auto& ch : fit->summary.channels) c.push_back({ch.name, fmt::format("{:.3f}", ch.noise_ratio)});
    report.AddTable({"channel", "pooled noise ratio"}, c, "about 1 at the noise floor");
  }
  report.Write(path);
}

}  // namespace strut::report
