// HTML reports: the document itself (escaping, inline plotly.js, no external sources, NaN as null,
// crash-safe writing), and a real browser: headless Chromium runs the report's scripts and
// plotly.js must have drawn every plot (docs/reports.md).
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "strut/ident/html_report.h"
#include "test_support.h"

namespace {

using strut::ident::ErrorBarSeries;
using strut::ident::HtmlReport;
using strut::ident::Series;
using strut::test::TempDir;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::string Lower(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(), [](unsigned char c) { return std::tolower(c); });
  return text;
}

using strut::test::ChromiumCommand;
using strut::test::Count;
using strut::test::kChromium;
using strut::test::ReadFile;
using strut::test::Shell;
using strut::test::ShellResult;

// The report the browser test opens: a line plot, a heat map and error bars.
HtmlReport MakeFullReport() {
  HtmlReport report("Identification of the 2 dof damper");
  report.AddHeading("Fit");
  report.AddParagraph("Residuals of the final estimate, per experiment.");
  Series measured{"measured force", {}, {}, "markers"};
  Series model{"model force", {}, {}};
  for (int i = 0; i <= 400; ++i) {
    const double t = i / 200.0;
    measured.x.push_back(t);
    model.x.push_back(t);
    model.y.push_back(1e4 * std::sin(2 * std::numbers::pi * t) + 2e3 * std::sin(6 * std::numbers::pi * t));
    measured.y.push_back(model.y.back() + 300 * std::cos(37.0 * i));
  }
  report.AddLinePlot("Force over time", "time [s]", "force [N]", {measured, model});
  Eigen::MatrixXd correlation(4, 4);
  correlation << 1.0, 0.82, -0.35, 0.1, 0.82, 1.0, -0.6, 0.05, -0.35, -0.6, 1.0, 0.4, 0.1, 0.05, 0.4, 1.0;
  report.AddHeatmap("Parameter correlation", {"theta1", "theta4", "theta9", "theta16"}, correlation, -1, 1);
  std::vector<std::string> experiments;
  ErrorBarSeries stroke{"stroke residual", {}, {}}, force{"force residual", {}, {}};
  for (int e = 1; e <= 14; ++e) {
    experiments.push_back(std::string("E").append(std::to_string(e)));
    stroke.mean.push_back(0.02 * std::sin(e));
    stroke.sigma.push_back(0.01 + 0.002 * e);
    force.mean.push_back(0.015 * std::cos(e));
    force.sigma.push_back(0.012);
  }
  report.AddErrorBars("Residual mean per experiment", "residual [-]", experiments, {stroke, force});
  report.AddTable({"parameter", "estimate", "sigma"}, {{"theta1", "2.5e6", "1.2e4"}, {"theta4", "0.31", "0.002"}},
                  "Estimates");
  return report;
}

TEST(HtmlReport, RendersOneSelfContainedDocument) {
  HtmlReport report("Damper <model> & \"friends\"");
  report.AddHeading("Section <1>");
  report.AddParagraph("This is <b>not bold</b> & stays text.");
  report.AddTable({"name", "value"}, {{"<script>", "1.5e3"}, {"plain", "n/a"}}, "Table <caption>");
  report.AddLinePlot("Line", "x", "y", {{"with gap", {0, 1, 2}, {1.0, kNaN, 3.0}}});
  report.AddPlot(nlohmann::json::array({{{"type", "scatter"},
                                         {"name", "</script><script>alert(1)</script>"},
                                         {"y", {std::numeric_limits<double>::infinity(), 2.0}}}}),
                 {{"title", {{"text", "raw"}}}}, "caption");
  const std::string html = report.Render();

  EXPECT_EQ(html.rfind("<!DOCTYPE html>", 0), 0u);
  EXPECT_NE(html.find("<title>Damper &lt;model&gt; &amp; &quot;friends&quot;</title>"), std::string::npos);
  EXPECT_NE(html.find("<h1>Damper &lt;model&gt; &amp; &quot;friends&quot;</h1>"), std::string::npos);
  EXPECT_NE(html.find("<h2>Section &lt;1&gt;</h2>"), std::string::npos);
  EXPECT_NE(html.find("<p>This is &lt;b&gt;not bold&lt;/b&gt; &amp; stays text.</p>"), std::string::npos);
  EXPECT_EQ(html.find("<b>not bold"), std::string::npos);
  EXPECT_NE(html.find("<caption>Table &lt;caption&gt;</caption>"), std::string::npos);
  EXPECT_NE(html.find("<td>&lt;script&gt;</td><td class=\"num\">1.5e3</td>"), std::string::npos);
  EXPECT_NE(html.find("Generated "), std::string::npos);

  // plotly.js inline, whole, once; its licence header kept.
  const std::string_view plotly = HtmlReport::PlotlyBundle();
  ASSERT_GT(plotly.size(), 1'000'000u);
  EXPECT_NE(plotly.substr(0, 400).find("plotly.js v"), std::string_view::npos);
  EXPECT_NE(plotly.substr(0, 400).find("MIT"), std::string_view::npos);
  const auto bundle_at = html.find(plotly);
  ASSERT_NE(bundle_at, std::string::npos);
  EXPECT_EQ(html.find(plotly, bundle_at + 1), std::string::npos);
  EXPECT_NE(html.find("responsive:true,displaylogo:false"), std::string::npos);
  // The bundle can be inlined: nothing in it ends the script element early.
  EXPECT_EQ(Lower(std::string(plotly)).find("</script"), std::string::npos);
  EXPECT_EQ(plotly.find("<!--"), std::string_view::npos);

  // The markup around the bundle (its own strings mention map-tile sites it never loads here).
  const std::string markup = html.substr(0, bundle_at) + html.substr(bundle_at + plotly.size());
  EXPECT_EQ(Count(markup, "Plotly.newPlot("), 2u);
  // Nothing loaded from elsewhere: no script or link sources at all, no URLs in attributes or CSS.
  const std::string lower = Lower(markup);
  EXPECT_EQ(lower.find("<script src"), std::string::npos);
  EXPECT_EQ(lower.find("<link"), std::string::npos);
  EXPECT_EQ(lower.find("http://"), std::string::npos);
  EXPECT_EQ(lower.find("https://"), std::string::npos);
  EXPECT_EQ(lower.find("url("), std::string::npos);

  // Data: NaN and Inf as null, compact JSON, strings cannot close the script element.
  EXPECT_NE(html.find("\"y\":[1.0,null,3.0]"), std::string::npos);
  EXPECT_NE(html.find("\"y\":[null,2.0]"), std::string::npos);
  EXPECT_EQ(markup.find("NaN"), std::string::npos);
  EXPECT_EQ(markup.find("Infinity"), std::string::npos);
  EXPECT_EQ(html.find("alert(1)</script>"), std::string::npos);
  EXPECT_NE(html.find("\\u003c/script>\\u003cscript>alert(1)"), std::string::npos);
  EXPECT_NE(html.find("<figcaption>caption</figcaption>"), std::string::npos);
}

TEST(HtmlReport, RejectsMismatchedSizes) {
  HtmlReport report("t");
  EXPECT_THROW(report.AddTable({"a", "b"}, {{"1"}}), std::invalid_argument);
  EXPECT_THROW(report.AddLinePlot("p", "x", "y", {{"s", {1, 2}, {1, 2, 3}}}), std::invalid_argument);
  EXPECT_THROW(report.AddHeatmap("h", {"a", "b"}, Eigen::MatrixXd::Identity(3, 3), -1, 1), std::invalid_argument);
  EXPECT_THROW(report.AddHeatmap("h", {"a"}, Eigen::MatrixXd::Identity(1, 1), 1, 1), std::invalid_argument);
  EXPECT_THROW(report.AddErrorBars("e", "y", {"a", "b"}, {{"s", {1, 2}, {1}}}), std::invalid_argument);
  EXPECT_THROW(report.AddPlot(nlohmann::json::object(), {}), std::invalid_argument);
  EXPECT_EQ(Count(report.Render(), "<figure>"), 0u);  // nothing half-added
}

TEST(HtmlReport, WritesCrashSafelyAndNamesThePathOnFailure) {
  TempDir dir;
  const std::string path = dir.file("report.html");
  HtmlReport report("written");
  report.AddParagraph("hello");
  report.Write(path);
  EXPECT_EQ(ReadFile(path), report.Render());
  EXPECT_FALSE(std::filesystem::exists(path + ".partial"));

  const std::string bad = dir.file("missing/dir/report.html");
  try {
    report.Write(bad);
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
  }
}

TEST(HtmlReport, RendersItsPlotsInHeadlessChromium) {
  if (access(kChromium, X_OK) != 0) {
    GTEST_SKIP() << kChromium << " not installed (scripts/install-deps.sh installs the Debian package chromium)";
  }
  TempDir dir;
  const std::string path = dir.file("report.html");
  MakeFullReport().Write(path);

  // The DOM after the scripts ran: plotly.js replaced each empty div by its SVG figure.
  const ShellResult dom =
      Shell(ChromiumCommand(dir.file("profile-dom")) + " --dump-dom file://" + path, dir.file("dom"));
  ASSERT_EQ(dom.exit_code, 0) << dom.err;
  const std::string& html = dom.out;
  EXPECT_EQ(Count(html, "class=\"plot-container plotly\""), 3u) << dom.err;
  EXPECT_GE(Count(html, "class=\"main-svg\""), 3u);  // plotly draws several SVG layers per plot
  // Legend entries and titles exist only as rendered SVG text (data-unformatted), not in the JSON.
  for (const char* text : {"measured force", "model force", "stroke residual", "force residual",
                           "Force over time", "Parameter correlation", "Residual mean per experiment"}) {
    EXPECT_NE(html.find(std::string("data-unformatted=\"") + text + "\""), std::string::npos) << text;
  }
  EXPECT_EQ(Count(html, "class=\"hm\""), 1u);         // the heat map image
  EXPECT_EQ(Count(html, "class=\"errorbar\""), 28u);  // one per experiment and series
  EXPECT_GE(Count(html, "class=\"js-line\""), 1u);    // the model line
  EXPECT_NE(html.find("data-unformatted=\"0.82\""), std::string::npos);  // a heat-map annotation
  // What plotly.js added refers to nothing outside the file (SVG namespaces aside); the modebar
  // has no plotly logo link (displaylogo: false).
  const std::string body = Lower(html.substr(html.find("<body")));
  EXPECT_EQ(body.find("src=\"http"), std::string::npos);
  EXPECT_EQ(body.find("href=\"http"), std::string::npos);
  EXPECT_EQ(body.find("url(http"), std::string::npos);
  EXPECT_EQ(body.find("plotly.com"), std::string::npos);

  // A screenshot: plots drawn make a large PNG (a blank page is a few kB).
  const std::string png = dir.file("report.png");
  const ShellResult shot = Shell(
      ChromiumCommand(dir.file("profile-shot")) + " --window-size=1200,1600 --screenshot=" + png + " file://" + path,
      dir.file("shot"));
  ASSERT_EQ(shot.exit_code, 0) << shot.err;
  ASSERT_TRUE(std::filesystem::exists(png)) << shot.err;
  EXPECT_GT(std::filesystem::file_size(png), 20'000u);
  EXPECT_EQ(ReadFile(png).substr(1, 3), "PNG");
  if (const char* keep = std::getenv("STRUT_KEEP_REPORT_SCREENSHOT")) {
    std::filesystem::copy_file(png, keep, std::filesystem::copy_options::overwrite_existing);
    std::filesystem::copy_file(path, std::string(keep) + ".html", std::filesystem::copy_options::overwrite_existing);
  }
}

}  // namespace
