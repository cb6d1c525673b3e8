// `strut rig run --monitor` against a real peer: headless Chromium loads the page a real --rig sim
// run serves, draws the traces and loops as the run goes on, shows a trip as an event within a
// second, and its pause button pauses the run, whose session stays valid; and `strut replay
// --monitor` shows a recorded session on the same page (docs/monitor.md).
#include <gtest/gtest.h>
#include <sys/socket.h>

#include <chrono>
#include <fstream>
#include <regex>
#include <thread>
#include <utility>

#include <spdlog/fmt/fmt.h>

#include "recorder_fixtures.h"
#include "session_events.h"
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

// `strut ARGS` on a thread while headless Chromium loads the monitor page it serves at `port`
// (with `fragment`, e.g. "#press-pause-on=trip"), once the port accepts. Chromium's virtual time
// runs out once the command has ended and the stream closed, and the DOM is dumped then.
std::pair<test::CommandResult, test::ShellResult> LoadPageWhileRunning(const TempDir& dir, int port,
                                                                       const std::string& args,
                                                                       const std::string& fragment) {
  test::CommandResult command;
  std::thread running([&] { command = RunStrut(args); });
  const auto start = std::chrono::steady_clock::now();
  while (!test::AcceptsOnLoopback(port) && std::chrono::steady_clock::now() - start < std::chrono::seconds(60))
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  test::ShellResult page = test::Shell(test::ChromiumCommand(dir.file("profile")) + " --dump-dom 'http://127.0.0.1:" +
                                           std::to_string(port) + "/" + fragment + "'",
                                       dir.file("chromium"));
  running.join();
  return {command, page};
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
  const auto [run, page] = LoadPageWhileRunning(
      dir, port,
      fmt::format("rig run --rig sim --speed 25 --no-top-out --matrix {} --limits {} --no-progress --monitor 127.0.0.1:{} "
                  "--monitor-control -o {}",
                  dir.file("m.toml"), dir.file("l.toml"), port, session),
      "#press-pause-on=trip");

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

TEST(MonitorCli, ChromiumDrawsAReplayedSessionWithItsExperimentsAndRecordedEventsThenShowsDisconnected) {
  if (!test::ChromiumAvailable()) GTEST_SKIP() << "no " << test::kChromium << " (scripts/install-deps.sh installs it)";
  TempDir dir;
  // Two experiments of 24 periods (12 s each at 2 Hz), events before, in and after them, played at
  // 2x: 12 s of wall time, the page connected for most of it even when Chromium takes several
  // seconds to start on a loaded machine (a 4 s replay left such a page 4 updates).
  const std::string session = dir.file("run.h5");
  test::RecordRunWithEvents(session, 24, 2.5);
  const auto recorded = test::SessionEvents(daq::ReadSession(session));
  ASSERT_EQ(recorded.size(), 4u);
  const int port = test::FreeLoopbackPort(SOCK_STREAM);
  const auto [replay, page] =
      LoadPageWhileRunning(dir, port, fmt::format("replay {} --speed 2 --monitor 127.0.0.1:{}", session, port), "");

  EXPECT_EQ(replay.exit_code, 0) << replay.output;
  EXPECT_NE(replay.output.find(fmt::format("monitor: http://127.0.0.1:{}/", port)), std::string::npos) << replay.output;
  EXPECT_NE(replay.output.find("at 2x"), std::string::npos) << replay.output;
  const std::string& dom = page.out;
  ASSERT_NE(dom.find("strut monitor"), std::string::npos) << page.err;
  EXPECT_NE(dom.find("replay of " + session), std::string::npos);  // the title
  EXPECT_EQ(HtmlData(dom, "error"), "");
  EXPECT_EQ(HtmlData(dom, "connection"), "disconnected");  // the replay ended: the page says so
  EXPECT_GE(std::stoi("0" + HtmlData(dom, "updates")), 10);
  EXPECT_GT(std::stoi("0" + HtmlData(dom, "trace-points")), 100);
  EXPECT_GT(std::stoi("0" + HtmlData(dom, "loop-points")), 20);
  // The matrix: the session's two experiments, both done once the replay is over.
  EXPECT_EQ(test::Count(dom, "— done"), 2u) << dom;
  EXPECT_NE(dom.find("<li class=\"done\">b: 2 Hz"), std::string::npos);
  // Every recorded event, in the recorded order: the page lists the newest first.
  EXPECT_EQ(HtmlData(dom, "events"), std::to_string(recorded.size()));
  EXPECT_EQ(HtmlData(dom, "last-event"), recorded.back().first);
  std::size_t at = std::string::npos;
  for (const auto& [kind, text] : recorded) {
    const std::size_t here = dom.find("<b>" + kind + "</b> " + text);
    ASSERT_NE(here, std::string::npos) << kind;
    if (at != std::string::npos) {
      EXPECT_LT(here, at) << kind << " is not listed above the event recorded before it";
    }
    at = here;
  }
}

TEST(MonitorCli, ReplayRefusesMonitorWithoutAPaceAndAnAddressItCannotTake) {
  TempDir dir;
  const std::string session = dir.file("run.h5");
  test::RecordRunWithEvents(session, 1, 0.2);
  const test::CommandResult max = RunStrut(fmt::format("replay {} --speed max --monitor 127.0.0.1:0", session));
  EXPECT_NE(max.exit_code, 0);
  EXPECT_NE(max.output.find("--speed max with --monitor"), std::string::npos) << max.output;
  const test::CommandResult bad = RunStrut(fmt::format("replay {} --monitor 127.0.0.1:99999", session));
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.output.find("--monitor '127.0.0.1:99999'"), std::string::npos) << bad.output;
  const test::CommandResult elsewhere = RunStrut(fmt::format("replay {} --monitor 192.0.2.1:0", session));
  EXPECT_NE(elsewhere.exit_code, 0);
  EXPECT_NE(elsewhere.output.find("cannot listen on 192.0.2.1"), std::string::npos) << elsewhere.output;
}

}  // namespace
}  // namespace strut
