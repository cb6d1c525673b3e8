// The identify and discover reports as a person opens them: written by the strut binary from a
// simulated session, rendered by headless Chromium, which must draw every plot (docs/reports.md).
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fmt/format.h>

#include <regex>
#include <string>

#include "session_fixtures.h"
#include "strut_cli.h"

namespace strut::ident {
namespace {

using test::ChromiumCommand;
using test::Count;
using test::kChromium;
using test::ReadFile;
using test::Shell;
using test::ShellResult;
using test::TempDir;

constexpr const char* kStandardLabels = "abcdefghijklmn";  // the 14 experiments of the standard matrix
constexpr std::uintmax_t kMaxReportBytes = 1'500'000;

//! The DOM after the report's scripts ran (Chromium's --dump-dom).
std::string RenderedDom(const TempDir& dir, const std::string& report) {
  const ShellResult dom = Shell(ChromiumCommand(dir.file("profile")) + " --dump-dom file://" + report, dir.file("dom"));
  EXPECT_EQ(dom.exit_code, 0) << dom.err;
  return dom.out;
}

//! Every figure div of the rendered page drew (data-drawn, one canvas each), and the page counted
//! them all; returns how many.
std::size_t ExpectEveryPlotDrawn(const std::string& dom) {
  const std::string body = dom.substr(std::min(dom.find("<body"), dom.size()));  // the head's script names the markers
  const std::size_t plots = Count(body, "class=\"plot\"");
  EXPECT_GT(plots, 0u);
  EXPECT_NE(dom.find("<html lang=\"en\" data-figures-drawn=\"" + std::to_string(plots) + "\">"), std::string::npos)
      << "not every plot drew";
  EXPECT_EQ(Count(body, "data-drawn=\"1\""), plots);
  EXPECT_EQ(Count(body, "<canvas"), plots);
  return plots;
}

//! A title as uPlot rendered it: a div of its own, which exists only after the script ran.
bool HasPlotTitle(const std::string& dom, const std::string& title) {
  return dom.find("<div class=\"u-title\">" + title + "</div>") != std::string::npos;
}

TEST(FitReport, IdentifyReportOfTheStandardMatrixOpensWithTheVerdictAndDrawsEveryPlot) {
  if (!test::ChromiumAvailable())
    GTEST_SKIP() << kChromium << " not installed (scripts/install-deps.sh installs the Debian package chromium)";
  TempDir dir;
  test::WriteTwoDofSession(dir.file("s.h5"), kStandardLabels);
  // 1dof on 2 dof data: converged above the noise floor, the verdict a user must not miss. The
  // default grid (800 points per period), so the size is the size a user gets.
  const auto run =
      test::RunStrut("identify " + dir.file("s.h5") + " --model 1dof --no-progress --report " + dir.file("r.html"));
  ASSERT_EQ(run.exit_code, 3) << run.output;
  const std::string html = ReadFile(dir.file("r.html"));
  EXPECT_LT(std::filesystem::file_size(dir.file("r.html")), kMaxReportBytes);

  // The verdict opens the report, before any table or plot.
  const auto main = html.find("<main>");
  ASSERT_NE(main, std::string::npos);
  EXPECT_EQ(html.find("<p class=\"callout warning\">Converged, but ABOVE THE NOISE FLOOR"),
            html.find("<p", main)) << html.substr(main, 400);
  EXPECT_NE(html.find("strut discover", main), std::string::npos);
  // One set of units: no "[SI]", kN and MPa in tables and plots alike; sd written with ±.
  EXPECT_EQ(html.find("[SI]"), std::string::npos);
  EXPECT_EQ(html.find("(SI)"), std::string::npos);
  EXPECT_NE(html.find("<td>kN²</td>"), std::string::npos);
  EXPECT_NE(html.find("\"y\":\"force residual [kN]"), std::string::npos);
  EXPECT_NE(html.find("\"y\":\"pressure [MPa]\""), std::string::npos);
  EXPECT_NE(html.find("residual variance v_b"), std::string::npos);
  EXPECT_TRUE(std::regex_search(html, std::regex("<td>[-0-9.e]+ ± [0-9.e-]+</td><td>kN</td>"))) << "friction in kN ± sd";

  const std::string dom = RenderedDom(dir, dir.file("r.html"));
  const std::size_t plots = ExpectEveryPlotDrawn(dom);
  // Per experiment: force and pressure overlays beside their residuals, two loops; plus the
  // residual bars of each channel, the correlation and the convergence.
  EXPECT_EQ(plots, 14u * 6u + 2u + 1u + 1u);
  for (const char label : std::string(kStandardLabels)) {
    for (const char* channel : {"force", "pressure"}) {
      EXPECT_TRUE(HasPlotTitle(dom, fmt::format("{}: {} residual, measured − predicted", label, channel)))
          << label << " " << channel;
      EXPECT_TRUE(HasPlotTitle(dom, fmt::format("{}: {}", label, channel))) << label << " " << channel;
    }
  }
  EXPECT_TRUE(dom.find("<p class=\"callout warning\">Converged, but ABOVE THE NOISE FLOOR") != std::string::npos);
  // The convergence plot counts the iterations the text counts.
  const std::regex iterations("after (\\d+) iterations");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(html, m, iterations));
  EXPECT_TRUE(HasPlotTitle(dom, "log-likelihood after each of the " + m[1].str() + " iterations"));
  EXPECT_EQ(Count(dom, "<div class=\"u-label\">± 2σ noise</div>"), 28u);  // the noise band on every residual
}

TEST(FitReport, DiscoverReportHoldsTheFinalModelAndSaysWhatItsNameMeans) {
  if (!test::ChromiumAvailable())
    GTEST_SKIP() << kChromium << " not installed (scripts/install-deps.sh installs the Debian package chromium)";
  TempDir dir;
  test::WriteTwoDofSession(dir.file("s.h5"), "bgkn");
  const auto run = test::RunStrut("discover " + dir.file("s.h5") + " --model 1dof --n 200 --report " +
                                  dir.file("d.html") + " --json " + dir.file("d.json"));
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const std::string html = ReadFile(dir.file("d.html"));
  EXPECT_LT(std::filesystem::file_size(dir.file("d.html")), kMaxReportBytes);
  EXPECT_EQ(html.find("[SI]"), std::string::npos);
  // From 1dof, discovery adds heat exchange and gas solubility: the model 2dof, and the report says so.
  EXPECT_NE(html.find("1dof+heat-exchange+gas-solubility is the model 2dof"), std::string::npos);
  // Signed ΔBIC, negative for a kept term, as the caption explains.
  EXPECT_NE(html.find("negative means the term explains more than its parameters cost"), std::string::npos);
  const auto added = html.find("<h2>What was added</h2>"), rounds = html.find("<caption>Round 1:");
  ASSERT_LT(added, rounds);
  const std::string steps = html.substr(added, rounds - added);
  EXPECT_TRUE(std::regex_search(steps, std::regex("<td>heat-exchange</td><td class=\"num\">-[0-9]+\\.[0-9]</td>")));
  EXPECT_TRUE(std::regex_search(steps, std::regex("<td>gas-solubility</td><td class=\"num\">-[0-9]+\\.[0-9]</td>")));
  EXPECT_EQ(steps.find("<td class=\"num\">+"), std::string::npos) << "a kept term's ΔBIC is negative";
  // Rejected candidates keep their sign: a term that does not pay for itself shows a positive ΔBIC.
  EXPECT_NE(html.find("(ΔBIC negative is better)"), std::string::npos);
  // The final model's parameter table and verdict.
  EXPECT_NE(html.find("<h2>The final model 2dof</h2>"), std::string::npos);
  EXPECT_NE(html.find("<td>theta16</td><td>wall_heat_conductance</td>"), std::string::npos);

  const std::string dom = RenderedDom(dir, dir.file("d.html"));
  const std::size_t plots = ExpectEveryPlotDrawn(dom);
  EXPECT_EQ(plots, 2u + 4u * 6u);  // residuals before and after per channel; the final model's plots
  for (const char label : std::string("bgkn"))
    EXPECT_TRUE(HasPlotTitle(dom, fmt::format("{}: force residual, measured − predicted", label))) << label;
  EXPECT_TRUE(HasPlotTitle(dom, "force residual per experiment, before and after"));
  EXPECT_NE(dom.find("<div class=\"u-label\">final 2dof</div>"), std::string::npos);
}

}  // namespace
}  // namespace strut::ident
