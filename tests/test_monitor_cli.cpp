// `strut rig run --monitor` against a real peer: headless Chromium loads the page a real --rig sim
// run serves, draws the traces and loops as the run goes on, shows a trip as an event within a
// second, and its pause button pauses the run, whose session stays valid (docs/monitor.md).
#include <gtest/gtest.h>
#include <sys/socket.h>

#include <chrono>
#include <fstream>
#include <regex>
#include <thread>

#include <spdlog/fmt/fmt.h>

#include "strut/daq/session.h"
#include "strut_cli.h"
#include "test_support.h"

namespace strut {
namespace {

using test::RunStrut;
using test::TempDir;

// The value of <html data-NAME="..."> in a DOM dump, "" when absent.
std::string HtmlData(const std::string& dom, const std::string& name) {
  std::smatch m;
  const std::regex pattern("<html[^>]* data-" + name + "=\"([^\"]*)\"");
  return std::regex_search(dom, m, pattern) ? m[1].str() : "";
}

TEST(MonitorCli, ChromiumDrawsARunLiveShowsATripAndItsPauseButtonPausesTheRun) {
  if (!test::ChromiumAvailable()) GTEST_SKIP() << "no " << test::kChromium << " (scripts/install-deps.sh installs it)";
  TempDir dir;
  // Three short experiments; a force limit between the first's force (about 5 kN at 133 mm) and
  // the second's (20 kN at 249 mm), with action indicate, trips on the way to the second and lets
  // the run go on; the page presses pause when that trip comes in.
  std::ofstream(dir.file("m.toml")) << "[[experiment]]\nlabel = \"p\"\nfrequency = 2.0\nstatic_position = 0.133\n"
                                       "amplitude = 0.01\n[[experiment]]\nlabel = \"q\"\nfrequency = 2.0\n"
                                       "static_position = 0.249\namplitude = 0.01\n[[experiment]]\nlabel = \"r\"\n"
                                       "frequency = 2.0\nstatic_position = 0.133\namplitude = 0.01\n";
  std::ofstream(dir.file("l.toml")) << "[force]\nupper = 12000.0\naction = \"indicate\"\n";
  const int port = test::FreeLoopbackPort(SOCK_STREAM);
  const std::string session = dir.file("s.h5");
  test::CommandResult run;
  std::thread runner([&] {
    run = RunStrut(fmt::format("rig run --rig sim --speed 25 --no-top-out --matrix {} --limits {} --no-progress --monitor 127.0.0.1:{} "
                               "--monitor-control -o {}",
                               dir.file("m.toml"), dir.file("l.toml"), port, session));
  });
  const auto start = std::chrono::steady_clock::now();
  while (!test::AcceptsOnLoopback(port) && std::chrono::steady_clock::now() - start < std::chrono::seconds(60))
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  // Chromium's virtual time runs out once the run
  // has ended and the stream closed, and the DOM is dumped then.
  const test::ShellResult page = test::Shell(
      test::ChromiumCommand(dir.file("profile")) + " --dump-dom 'http://127.0.0.1:" + std::to_string(port) + "/#press-pause-on=trip'",
      dir.file("chromium"));
  runner.join();

  EXPECT_EQ(run.exit_code, 4) << run.output;  // paused after the experiment in progress
  EXPECT_NE(run.output.find("pause requested from the page"), std::string::npos) << run.output;
  const daq::Session s = daq::ReadSession(session);  // valid
  // Paused after q, in which the trip came and the page pressed: p and q complete, r to come.
  ASSERT_EQ(s.experiments.size(), 2u) << run.output;
  for (const daq::Experiment& e : s.experiments) EXPECT_EQ(e.status, "complete") << e.label << run.output;

  const std::string& dom = page.out;
  ASSERT_NE(dom.find("strut monitor"), std::string::npos) << page.err;
  EXPECT_EQ(HtmlData(dom, "error"), "");
  EXPECT_EQ(HtmlData(dom, "connection"), "disconnected");  // the run ended: the page says so
  EXPECT_GE(std::stoi("0" + HtmlData(dom, "updates")), 10);
  EXPECT_GE(std::stoi("0" + HtmlData(dom, "drawn")), 1);
  EXPECT_GT(std::stoi("0" + HtmlData(dom, "trace-points")), 100);  // the three traces
  EXPECT_GT(std::stoi("0" + HtmlData(dom, "loop-points")), 20);    // the loops of the experiment
  const std::string trip_delay = HtmlData(dom, "trip-delay");
  ASSERT_FALSE(trip_delay.empty()) << "no trip event reached the page";
  EXPECT_LT(std::stod(trip_delay), 1.0);
  EXPECT_NE(dom.find("force-limit"), std::string::npos);  // the trip's text in the event list
  EXPECT_EQ(HtmlData(dom, "last-event"), "paused");
}

}  // namespace
}  // namespace strut
