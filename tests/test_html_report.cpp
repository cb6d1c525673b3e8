// HTML reports: the document itself (escaping, the plotting script inline, no external sources,
// NaN as null, shared and rounded number arrays, thinning, crash-safe writing), and a real browser:
// headless Chromium runs the report's scripts and every plot must have drawn (docs/reports.md).
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

#include "strut/report/html_report.h"
#include "test_support.h"

namespace {

using strut::report::ErrorBarSeries;
using strut::report::HtmlReport;
using strut::report::Series;
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
  report.AddCallout("Converged <at> the noise floor.", strut::report::Tone::kGood);
  report.AddTable({"name", "value"}, {{"<script>", "1.5e3"}, {"plain", "n/a"}}, "Table <caption>");
  report.AddLinePlot("Line", "x", "y", {{"with gap", {0, 1, 2}, {1.0, kNaN, 3.0}}});
  report.AddLinePlot("</script><script>alert(1)</script>", "x", "y",
                     {{"</script><!--", {}, {std::numeric_limits<double>::infinity(), 2.0}}});
  const std::string html = report.Render();

  EXPECT_EQ(html.rfind("<!DOCTYPE html>", 0), 0u);
  EXPECT_NE(html.find("<title>Damper &lt;model&gt; &amp; &quot;friends&quot;</title>"), std::string::npos);
  EXPECT_NE(html.find("<h1>Damper &lt;model&gt; &amp; &quot;friends&quot;</h1>"), std::string::npos);
  EXPECT_NE(html.find("<h2>Section &lt;1&gt;</h2>"), std::string::npos);
  EXPECT_NE(html.find("<p>This is &lt;b&gt;not bold&lt;/b&gt; &amp; stays text.</p>"), std::string::npos);
  EXPECT_EQ(html.find("<b>not bold"), std::string::npos);
  EXPECT_NE(html.find("<p class=\"callout good\">Converged &lt;at&gt; the noise floor.</p>"), std::string::npos);
  EXPECT_NE(html.find("<caption>Table &lt;caption&gt;</caption>"), std::string::npos);
  EXPECT_NE(html.find("<td>&lt;script&gt;</td><td class=\"num\">1.5e3</td>"), std::string::npos);
  EXPECT_NE(html.find("Generated "), std::string::npos);

  // The plotting script inline, whole, once: uPlot with its licence banner, then strut's figures.
  const std::string_view script = HtmlReport::PlotScript();
  ASSERT_GT(script.size(), 40'000u);
  EXPECT_LT(script.size(), 120'000u);  // the point of uPlot: a report is mostly its data
  EXPECT_EQ(script.substr(0, 200).find("/*! uPlot v1.6.32 | Copyright (c)"), 0u) << script.substr(0, 200);
  EXPECT_NE(script.substr(0, 200).find("MIT License"), std::string_view::npos);
  EXPECT_NE(script.find("window.strutDrawFigures"), std::string_view::npos);
  const auto script_at = html.find(script);
  ASSERT_NE(script_at, std::string::npos);
  EXPECT_EQ(html.find(script, script_at + 1), std::string::npos);
  EXPECT_NE(html.find(HtmlReport::PlotStyle()), std::string::npos);
  EXPECT_NE(HtmlReport::PlotStyle().find(".uplot"), std::string_view::npos);
  // The script can be inlined: nothing in it ends the script element early.
  EXPECT_EQ(Lower(std::string(script)).find("</script"), std::string::npos);
  EXPECT_EQ(script.find("<!--"), std::string_view::npos);

  // The markup around the script (uPlot's banner names its home page).
  const std::string markup = html.substr(0, script_at) + html.substr(script_at + script.size());
  EXPECT_EQ(Count(markup, "strutDrawFigures(["), 1u);
  EXPECT_EQ(Count(markup, "\"kind\":\"xy\""), 2u);
  // Nothing loaded from elsewhere: no script or link sources at all, no URLs in attributes or CSS.
  const std::string lower = Lower(markup);
  EXPECT_EQ(lower.find("<script src"), std::string::npos);
  EXPECT_EQ(lower.find("<link"), std::string::npos);
  EXPECT_EQ(lower.find("http://"), std::string::npos);
  EXPECT_EQ(lower.find("https://"), std::string::npos);
  EXPECT_EQ(lower.find("url("), std::string::npos);

  // Data: NaN and Inf as null, strings cannot close the script element or open a comment.
  EXPECT_NE(markup.find("[1,null,3]"), std::string::npos);
  EXPECT_NE(markup.find("[null,2]"), std::string::npos);
  EXPECT_EQ(markup.find("NaN"), std::string::npos);
  EXPECT_EQ(markup.find("Infinity"), std::string::npos);
  EXPECT_EQ(html.find("alert(1)</script>"), std::string::npos);
  EXPECT_NE(html.find("\\u003c/script>\\u003cscript>alert(1)"), std::string::npos);
  EXPECT_EQ(Count(markup, "<!--"), 0u);
}

// Arrays are written once however many plots use them, at 1e-5 of their range.
TEST(HtmlReport, WritesEachNumberArrayOnceRoundedToItsRange) {
  HtmlReport report("data");
  const std::vector<double> t{0.0, 0.25, 0.5, 0.75};
  report.AddLinePlots({{"a", "t", "force", {{"one", t, {1234.56789, 1200.0, 1100.0, 1000.0}}}},
                       {"b", "t", "stroke", {{"two", t, {0.1234567891, 0.1234667891, -0.0000001, 0.0}}}}},
                      "side by side");
  report.AddLinePlot("c", "t", "force", {{"again", t, {1234.56789, 1200.0, 1100.0, 1000.0}}});
  const std::string html = report.Render();
  EXPECT_EQ(Count(html, "<div class=\"row\">"), 1u);
  EXPECT_NE(html.find("<p class=\"row-caption\">side by side</p>"), std::string::npos);
  // Range 234.6: resolution 2.3e-3, three decimals; 0.75: six; trailing zeros and -0 dropped.
  const auto data = html.find("var strutData=[");
  ASSERT_NE(data, std::string::npos);
  const std::string arrays = html.substr(data, html.find("];\nstrutDrawFigures", data) - data);
  EXPECT_EQ(Count(arrays, "[0,0.25,0.5,0.75]"), 1u) << arrays;
  EXPECT_EQ(Count(arrays, "[1234.568,1200,1100,1000]"), 1u) << arrays;
  EXPECT_EQ(Count(arrays, "[0.123457,0.123467,0,0]"), 1u) << arrays;
  EXPECT_EQ(Count(arrays, "\n"), 2u) << "three arrays, one line each";
}

// A series longer than kMaxPlotPoints keeps its envelope: every run's lowest and highest point.
TEST(HtmlReport, ThinsLongSeriesToTheirEnvelope) {
  HtmlReport report("long");
  Series s{"long", {}, {}};
  const std::size_t n = 100'000;
  for (std::size_t i = 0; i < n; ++i) s.y.push_back(i == 54'321 ? 7.0 : i == 9'876 ? -5.0 : std::sin(0.001 * i));
  report.AddLinePlot("long", "sample", "y", {s});
  const std::string html = report.Render();
  const auto data = html.find("var strutData=[");
  const std::string arrays = html.substr(data, html.find("];\nstrutDrawFigures", data) - data);
  // x (made explicit) and y, each at most kMaxPlotPoints numbers.
  EXPECT_EQ(Count(arrays, "\n"), 1u);
  const std::string y = arrays.substr(arrays.find('\n') + 1);
  EXPECT_LE(Count(y, ","), HtmlReport::kMaxPlotPoints);
  EXPECT_GE(Count(y, ","), HtmlReport::kMaxPlotPoints / 2);
  EXPECT_NE(y.find(",7,"), std::string::npos);
  EXPECT_NE(y.find(",-5,"), std::string::npos);
  EXPECT_NE(arrays.find(",54321,"), std::string::npos);  // its sample number kept with it
  EXPECT_NE(arrays.find(",99999]"), std::string::npos);  // the last point too
}

TEST(HtmlReport, RejectsMismatchedSizes) {
  HtmlReport report("t");
  EXPECT_THROW(report.AddTable({"a", "b"}, {{"1"}}), std::invalid_argument);
  EXPECT_THROW(report.AddLinePlot("p", "x", "y", {{"s", {1, 2}, {1, 2, 3}}}), std::invalid_argument);
  EXPECT_THROW(report.AddHeatmap("h", {"a", "b"}, Eigen::MatrixXd::Identity(3, 3), -1, 1), std::invalid_argument);
  EXPECT_THROW(report.AddHeatmap("h", {"a"}, Eigen::MatrixXd::Identity(1, 1), 1, 1), std::invalid_argument);
  EXPECT_THROW(report.AddErrorBars("e", "y", {"a", "b"}, {{"s", {1, 2}, {1}}}), std::invalid_argument);
  EXPECT_THROW(report.AddLinePlots({{"fine", "x", "y", {{"s", {1, 2}, {1, 2}}}}, {"bad", "x", "y", {{"s", {1}, {1, 2}}}}}),
               std::invalid_argument);
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

  // The DOM after the scripts ran: each figure's empty <div> now holds a uPlot chart (a canvas,
  // its title and legend as HTML) and is marked drawn; the page counts the figures that drew.
  const ShellResult dom =
      Shell(ChromiumCommand(dir.file("profile-dom")) + " --dump-dom file://" + path, dir.file("dom"));
  ASSERT_EQ(dom.exit_code, 0) << dom.err;
  EXPECT_NE(dom.out.find("<html lang=\"en\" data-figures-drawn=\"3\">"), std::string::npos) << dom.err;
  const std::string html = dom.out.substr(dom.out.find("<body"));  // the head's script mentions the markers
  EXPECT_EQ(html.find("data-figures-failed"), std::string::npos);
  EXPECT_EQ(Count(html, "data-drawn=\"1\""), 3u);
  EXPECT_EQ(Count(html, "<canvas"), 3u);
  // Titles and legend entries exist only as rendered HTML, not in the figure JSON's form.
  for (const char* title : {"Force over time", "Parameter correlation", "Residual mean per experiment"})
    EXPECT_NE(html.find(std::string("<div class=\"u-title\">") + title + "</div>"), std::string::npos) << title;
  for (const char* label : {"measured force", "model force", "stroke residual", "force residual"})
    EXPECT_NE(html.find(std::string("<div class=\"u-label\">") + label + "</div>"), std::string::npos) << label;
  EXPECT_NE(html.find("data-bars=\"28\""), std::string::npos);  // one error bar per experiment and series
  EXPECT_NE(html.find("<div class=\"readout\">"), std::string::npos);
  // What the script added refers to nothing outside the file.
  const std::string body = Lower(html.substr(html.find("<body")));
  EXPECT_EQ(body.find("src=\"http"), std::string::npos);
  EXPECT_EQ(body.find("href=\"http"), std::string::npos);
  EXPECT_EQ(body.find("url(http"), std::string::npos);

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
