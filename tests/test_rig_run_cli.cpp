// `strut rig run` as a process (tools/cmd_rig_run.cpp, docs/rig-run.md) against a rig reachable from
// another process: the plant of tests/support/rig_plant.h served over Modbus TCP by
// daq::ModbusControllerServer in this test, its samples streamed as CAN frames over UDP. A matrix
// beyond the limits is refused before the rig moves; a run killed with SIGKILL mid-experiment and
// resumed with --resume completes the matrix into the same session file.
#include <gtest/gtest.h>
#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <spdlog/fmt/fmt.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <utility>

#include "rig_plant.h"
#include "session_events.h"
#include "strut/daq/can_transport.h"
#include "strut/daq/modbus_controller.h"
#include "strut/daq/recorder.h"
#include "strut/daq/session.h"
#include "strut_cli.h"

namespace strut::rig {
namespace {

using test::Plant;
using test::PlantOptions;
using test::TempDir;
namespace fs = std::filesystem;

// The rig of another process: the plant's controller over Modbus TCP, its module over UDP.
struct RemoteRig {
  explicit RemoteRig(PlantOptions o = {}, daq::CanFrameLayout layout = test::PlantCanStreamer::Layout(),
                     std::vector<daq::ChannelDescriptor> channels = test::PlantChannels())
      : plant(o), server(plant), udp_port(test::FreeLoopbackPort(SOCK_DGRAM)) {
    streamer = std::make_unique<test::PlantCanStreamer>(
        plant, daq::UdpCanTransport::Connect("127.0.0.1", static_cast<std::uint16_t>(udp_port)), layout,
        std::move(channels));
  }
  std::string Args() const {
    // --drift-window 0: the plant has no thermal drift and the test runs in real time; --no-top-out:
    // nor a top-out stop, and a search in real time would take minutes (RigRunCli.ATopOutReference...).
    return fmt::format("--rig modbus-tcp://127.0.0.1:{} --daq udp:127.0.0.1:{} --daq-rate {} --drift-window 0 --no-top-out",
                       server.port(), udp_port, plant.options().sample_rate);
  }
  //! The same without --no-top-out: the run starts with the top-out reference.
  std::string ArgsWithTopOut() const {
    return fmt::format("--rig modbus-tcp://127.0.0.1:{} --daq udp:127.0.0.1:{} --daq-rate {} --drift-window 0",
                       server.port(), udp_port, plant.options().sample_rate);
  }
  Plant plant;
  daq::ModbusControllerServer server;
  int udp_port;
  std::unique_ptr<test::PlantCanStreamer> streamer;
};

void WriteFile(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

TEST(RigRunCli, AMatrixBeyondTheLimitsIsRefusedBeforeTheRigMoves) {
  TempDir dir;
  RemoteRig rig;
  WriteFile(dir.file("m.toml"), R"([[experiment]]
label = "ok"
frequency = 5.0
static_position = 0.12
amplitude = 0.01
[[experiment]]
label = "deep"
frequency = 5.0
static_position = 0.25
amplitude = 0.03
)");
  WriteFile(dir.file("l.toml"), "[stroke]\nupper = 0.26\n[actuator]\nmax_velocity = 0.8\n");
  const auto r = test::RunStrut(fmt::format("rig run {} --matrix {} --limits {} --serial S1 -o {}", rig.Args(),
                                            dir.file("m.toml"), dir.file("l.toml"), dir.file("s.h5")));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("is refused before the rig moves (limits: " + dir.file("l.toml") + ")"), std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("experiment 'deep': stroke 0.22 .. 0.28 m leaves the stroke limit -0.008 .. 0.26 m"),
            std::string::npos)
      << r.output;
  // 2 pi 5 Hz 0.03 m = 0.9425 m/s.
  EXPECT_NE(r.output.find("experiment 'deep': peak velocity 2 pi f A = 0.9425 m/s exceeds the velocity limit 0.8 m/s"),
            std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find("experiment 'ok'"), std::string::npos) << r.output;
  EXPECT_TRUE(rig.plant.applied().empty());
  EXPECT_TRUE(rig.plant.commands().empty());
  EXPECT_FALSE(fs::exists(dir.file("s.h5")));
  EXPECT_FALSE(fs::exists(daq::JournalPath(dir.file("s.h5"))));
  // The top-out reference is part of the check: limits that forbid its search are refused, before
  // anything moves, naming the search and the limit (and the way out).
  WriteFile(dir.file("shallow.toml"), "[stroke]\nlower = -0.004\n");
  const auto shallow = test::RunStrut(fmt::format("rig run {} --limits {} --serial S1 -o {}", rig.ArgsWithTopOut(),
                                                  dir.file("shallow.toml"), dir.file("s.h5")));
  EXPECT_EQ(shallow.exit_code, 1) << shallow.output;
  EXPECT_NE(shallow.output.find("the matrix standard is refused before the rig moves (limits: " + dir.file("shallow.toml") +
                                "):\n  top-out reference: the search -0.007 .. 0.007 m leaves the stroke limit -0.004 .. "
                                "0.27 m (give --top-out-to inside it, or --no-top-out)"),
            std::string::npos)
      << shallow.output;
  WriteFile(dir.file("tension.toml"), "[force]\nlower = -15000.0\n");
  const auto pulling = test::RunStrut(fmt::format("rig run {} --top-out-force 20000 --limits {} --serial S1 -o {}",
                                                  rig.ArgsWithTopOut(), dir.file("tension.toml"), dir.file("s.h5")));
  EXPECT_EQ(pulling.exit_code, 1) << pulling.output;
  EXPECT_NE(pulling.output.find("top-out reference: its force limit of 2e+04 N below the trend reaches the force limit "
                                "-1.5e+04 N"),
            std::string::npos)
      << pulling.output;
  EXPECT_TRUE(rig.plant.applied().empty());
  EXPECT_TRUE(rig.plant.commands().empty());
  EXPECT_FALSE(fs::exists(dir.file("s.h5")));
  // Bad limits files are named with their line; a new session needs a serial.
  WriteFile(dir.file("bad.toml"), "[stroke]\nupper = 0.26\nsideways = 1\n");
  const auto bad = test::RunStrut(fmt::format("rig run {} --limits {} --serial S1 -o {}", rig.Args(), dir.file("bad.toml"),
                                              dir.file("s.h5")));
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.output.find(dir.file("bad.toml") + ":3: [stroke] unknown key 'sideways'"), std::string::npos) << bad.output;
  const auto no_serial = test::RunStrut(fmt::format("rig run {} -o {}", rig.Args(), dir.file("s.h5")));
  EXPECT_EQ(no_serial.exit_code, 1);
  EXPECT_NE(no_serial.output.find("--serial"), std::string::npos) << no_serial.output;
  const auto no_journal = test::RunStrut(fmt::format("rig run {} -o {} --resume", rig.Args(), dir.file("s.h5")));
  EXPECT_EQ(no_journal.exit_code, 1);
  EXPECT_NE(no_journal.output.find("has no journal"), std::string::npos) << no_journal.output;
}

// Starts a shell command line (its redirections included) as a child process: its pid, or -1.
pid_t SpawnShell(const std::string& command_line) { return test::Spawn({"/bin/sh", "-c", "exec " + command_line}); }

TEST(RigRunCli, KillNineMidExperimentThenResumeCompletesTheMatrixIntoTheSameFile) {
  TempDir dir;
  RemoteRig rig;
  std::string matrix = "periods = 4\n";
  for (const char* label : {"a", "b", "c", "d"}) {
    matrix += fmt::format("[[experiment]]\nlabel = \"{}\"\nfrequency = 5.0\nstatic_position = {}\namplitude = 0.01\n",
                          label, label[0] == 'b' ? 0.14 : 0.12);
  }
  WriteFile(dir.file("m.toml"), matrix);
  const std::string session = dir.file("s.h5");
  const std::string common = fmt::format("{} rig run {} --matrix {} --ramp-cycles 1 --static-rate 0.5 -o {}",
                                         STRUT_BINARY, rig.Args(), dir.file("m.toml"), session);
  const pid_t pid = SpawnShell(common + " --serial K9 --no-progress > " + dir.file("first.log") + " 2>&1");
  ASSERT_GT(pid, 0);
  // Kill it once 'a' is recorded and 'b' is being recorded (the journal shows both).
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  bool in_b = false;
  while (!in_b && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    int early = 0;
    ASSERT_EQ(waitpid(pid, &early, WNOHANG), 0) << "the run ended early:\n" << test::ReadFile(dir.file("first.log"));
    if (!fs::exists(daq::JournalPath(session))) continue;
    try {
      const daq::Session s = daq::ReadJournal(daq::JournalPath(session));
      in_b = s.experiments.size() == 2 && s.experiments[0].status == "complete" && s.experiments[1].sample_count() > 100;
    } catch (const std::exception&) {
    }
  }
  ASSERT_TRUE(in_b) << test::ReadFile(dir.file("first.log"));
  ASSERT_EQ(kill(pid, SIGKILL), 0);
  int status = 0;
  waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFSIGNALED(status));
  EXPECT_FALSE(fs::exists(session));  // only the journal: the run never closed
  // The controller's watchdog notices the silence and stops the sine (heartbeat lost, latched).
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));

  const auto resumed = test::RunStrut(common.substr(std::string(STRUT_BINARY).size() + 1) + " --resume --no-progress");
  ASSERT_EQ(resumed.exit_code, 0) << resumed.output;
  EXPECT_NE(resumed.output.find("run complete"), std::string::npos) << resumed.output;
  // Not a terminal: plain log lines, one a phase, with the steady-state measure and the margins.
  EXPECT_NE(resumed.output.find("[info] c (2/3): recording (cycle "), std::string::npos) << resumed.output;
  EXPECT_NE(resumed.output.find("margins stroke "), std::string::npos) << resumed.output;
  EXPECT_FALSE(fs::exists(daq::JournalPath(session)));
  const daq::Session s = daq::ReadSession(session);
  EXPECT_EQ(s.damper_serial, "K9");
  ASSERT_EQ(s.experiments.size(), 5u);
  const std::vector<std::pair<std::string, std::string>> expected{
      {"a", "complete"}, {"b", "aborted"}, {"b-2", "complete"}, {"c", "complete"}, {"d", "complete"}};
  for (std::size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(s.experiments[i].label, expected[i].first);
    EXPECT_EQ(s.experiments[i].status, expected[i].second) << expected[i].first;
    if (expected[i].second == "complete") {
      EXPECT_EQ(s.experiments[i].sample_count(), 800u) << expected[i].first;
    }
  }
  EXPECT_GT(s.experiments[1].sample_count(), 100u);  // what the killed run recorded of 'b' is kept
  std::string events;
  for (const auto& [kind, text] : test::SessionEvents(s)) events += kind + ": " + text + "\n";
  EXPECT_NE(events.find("recovered: experiment 'b' was in progress"), std::string::npos) << events;
  EXPECT_NE(events.find("resumed: strut rig run --resume"), std::string::npos) << events;
  EXPECT_NE(events.find("reset: the controller latched heartbeat-lost"), std::string::npos) << events;
  // A completed session has nothing left to resume, and is not overwritten without --force.
  const auto again = test::RunStrut(common.substr(std::string(STRUT_BINARY).size() + 1) + " --serial K9");
  EXPECT_EQ(again.exit_code, 1);
  EXPECT_NE(again.output.find("--force"), std::string::npos) << again.output;
}

// Waits until the run writing `session` records the `n`th experiment (more than 100 samples of
// it in the journal); false when it ended or the minute passed first.
bool RecordingExperiment(pid_t pid, const std::string& session, std::size_t n) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    int early = 0;
    if (waitpid(pid, &early, WNOHANG) != 0) return false;
    if (!fs::exists(daq::JournalPath(session))) continue;
    try {
      const daq::Session s = daq::ReadJournal(daq::JournalPath(session));
      if (s.experiments.size() == n && s.experiments.back().sample_count() > 100) return true;
    } catch (const std::exception&) {
    }
  }
  return false;
}

int ExitStatus(pid_t pid) {
  int status = 0;
  waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// The operator's signals (tools/cmd_rig_run.cpp): Ctrl-C once pauses after the experiment in
// progress, SIGTERM stops at once; both exit 4 and resume with --resume.
TEST(RigRunCli, CtrlCPausesAfterTheExperimentAndSigtermStopsAtOnce) {
  TempDir dir;
  RemoteRig rig;
  WriteFile(dir.file("m.toml"), "periods = 4\n[[experiment]]\nlabel = \"a\"\nfrequency = 5.0\nstatic_position = 0.12\n"
                                "amplitude = 0.01\n[[experiment]]\nlabel = \"b\"\nfrequency = 5.0\n"
                                "static_position = 0.12\namplitude = 0.01\n");
  const std::string session = dir.file("s.h5");
  const std::string common = fmt::format("{} rig run {} --matrix {} --ramp-cycles 1 --static-rate 0.5 --no-progress -o {}",
                                         STRUT_BINARY, rig.Args(), dir.file("m.toml"), session);
  const pid_t first = SpawnShell(common + " --serial SG > " + dir.file("first.log") + " 2>&1");
  ASSERT_GT(first, 0);
  ASSERT_TRUE(RecordingExperiment(first, session, 1)) << test::ReadFile(dir.file("first.log"));
  ASSERT_EQ(kill(first, SIGINT), 0);
  EXPECT_EQ(ExitStatus(first), 4) << test::ReadFile(dir.file("first.log"));
  const std::string paused = test::ReadFile(dir.file("first.log"));
  EXPECT_NE(paused.find("paused at the operator's request before experiment 'b'"), std::string::npos) << paused;

  const pid_t second = SpawnShell(common + " --resume > " + dir.file("second.log") + " 2>&1");
  ASSERT_GT(second, 0);
  ASSERT_TRUE(RecordingExperiment(second, session, 2)) << test::ReadFile(dir.file("second.log"));
  ASSERT_EQ(kill(second, SIGTERM), 0);
  EXPECT_EQ(ExitStatus(second), 4) << test::ReadFile(dir.file("second.log"));
  const std::string stopped = test::ReadFile(dir.file("second.log"));
  EXPECT_NE(stopped.find("operator-stop: stop requested by the operator"), std::string::npos) << stopped;
  const daq::Session s = daq::ReadJournal(daq::JournalPath(session));
  ASSERT_EQ(s.experiments.size(), 2u);
  EXPECT_EQ(s.experiments[0].status, "complete");
  EXPECT_EQ(s.experiments[1].status, "aborted");
}

// One 5 Hz experiment, quick moves: a run of a few seconds on the plant.
const char* kOneExperiment = "periods = 4\n[[experiment]]\nlabel = \"a\"\nfrequency = 5.0\nstatic_position = 0.12\n"
                             "amplitude = 0.01\n";

// Largest |recorded force - the plant's force of the recorded stroke| over the record, and the
// force's half range (backward differences for the velocity, as the plant's own).
std::pair<double, double> ForceMismatch(const daq::Experiment& e, const Plant& plant) {
  const auto& stroke = e.channel("stroke").samples;
  const auto& force = e.channel("force").samples;
  double worst = 0.0;
  for (std::size_t i = 1; i < stroke.size(); ++i) {
    const double v = (stroke[i] - stroke[i - 1]) * e.sample_rate;
    worst = std::max(worst, std::abs(force[i] - plant.ForceOf(stroke[i], v, 0.0)));
  }
  const auto [lo, hi] = std::minmax_element(force.begin(), force.end());
  return {worst, 0.5 * (*hi - *lo)};
}

TEST(RigRunCli, AChannelFileRecordsAModuleOfAnotherLayoutAndCalibration) {
  TempDir dir;
  WriteFile(dir.file("m.toml"), kOneExperiment);
  // Module 7 sends CAN FD frames of four readings: pressure, a temperature nobody records, force
  // and stroke, calibrated in bar, kN and mm; the file says so in the calibration sheet's units.
  daq::CanFrameLayout layout;
  layout.module = 7;
  layout.fd = true;
  layout.channels = 4;
  const daq::Calibration stroke{5e-6, 0.15, -0.01, 0.31}, force{2.0, 0.0, -6e4, 6e4}, pressure{400.0, 1e7, -1e5, 2e7};
  RemoteRig rig({}, layout, {{"pressure", "Pa", pressure}, {"temperature", "K", {}}, {"force", "N", force},
                             {"stroke", "m", stroke}});
  WriteFile(dir.file("channels.toml"), R"(module = 7
frame = "fd"
channels = 4
[stroke]
index = 3
unit = "mm"
gain = 0.005
offset = 150.0
[force]
index = 2
unit = "kN"
gain = 0.002
[pressure]
index = 0
unit = "bar"
gain = 0.004
offset = 100.0
range_min = -1.0
range_max = 200.0
)");
  const std::string args = fmt::format("rig run {} --matrix {} --ramp-cycles 1 --static-rate 0.5 --serial CH1 --no-progress",
                                       rig.Args(), dir.file("m.toml"));
  const auto with_file = test::RunStrut(fmt::format("{} --channels {} -o {}", args, dir.file("channels.toml"),
                                                    dir.file("with.h5")));
  ASSERT_EQ(with_file.exit_code, 0) << with_file.output;
  const daq::Session s = daq::ReadSession(dir.file("with.h5"));
  ASSERT_EQ(s.experiments.size(), 1u);
  const daq::Experiment& e = s.experiments.front();
  EXPECT_EQ(e.status, "complete");
  const auto& strokes = e.channel("stroke").samples;
  const auto [lo, hi] = std::minmax_element(strokes.begin(), strokes.end());
  EXPECT_NEAR(0.5 * (*hi - *lo), 0.01, 1e-5);  // 5 um a count
  EXPECT_NEAR(0.5 * (*hi + *lo), 0.12, 1e-5);
  // Counts of 2 N and 5 um x 4 kN s/m / 1 ms: 22 N at worst.
  EXPECT_LT(ForceMismatch(e, rig.plant).first, 25.0);
  const auto& p = e.channel("pressure").samples;
  for (std::size_t i = 0; i < p.size(); i += 13)
    EXPECT_NEAR(p[i], rig.plant.options().pressure0 + rig.plant.options().pressure_per_m * strokes[i], 450.0) << i;
  // The reading nobody named is kept in counts.
  EXPECT_EQ(e.channel("channel1").samples.front(), 1234.0);

  // Without the file the run expects module 1's classic frames: nothing it can decode arrives, the
  // stale-data detector stops the run (exit 5) before anything is recorded.
  const auto without = test::RunStrut(fmt::format("{} -o {}", args, dir.file("without.h5")));
  EXPECT_EQ(without.exit_code, 5) << without.output;
  EXPECT_NE(without.output.find("stale"), std::string::npos) << without.output;
  EXPECT_NE(without.output.find("remaining: a"), std::string::npos) << without.output;
}

TEST(RigRunCli, WithoutItsChannelFileAnotherCalibrationIsMisRecorded) {
  TempDir dir;
  WriteFile(dir.file("m.toml"), kOneExperiment);
  // The default layout (module 1, classic, stroke force pressure) but a load cell of 2 N a count
  // about zero, where the default calibration has 120 kN / 65535 counts about 0.92 N.
  std::vector<daq::ChannelDescriptor> channels = test::PlantChannels();
  channels[1].calibration = {2.0, 0.0, -6e4, 6e4};
  RemoteRig rig({}, test::PlantCanStreamer::Layout(), channels);
  std::string file = "module = 1\nframe = \"classic\"\n";
  for (std::size_t k = 0; k < channels.size(); ++k) {
    const daq::ChannelDescriptor& c = channels[k];
    file += fmt::format("[{}]\nindex = {}\nunit = \"{}\"\ngain = {:.17g}\noffset = {:.17g}\n", c.name, k, c.unit,
                        c.calibration.gain, c.calibration.offset);
  }
  WriteFile(dir.file("channels.toml"), file);
  const std::string args = fmt::format("rig run {} --matrix {} --ramp-cycles 1 --static-rate 0.5 --serial CH2 --no-progress",
                                       rig.Args(), dir.file("m.toml"));
  const auto without = test::RunStrut(fmt::format("{} -o {}", args, dir.file("without.h5")));
  ASSERT_EQ(without.exit_code, 0) << without.output;
  const auto with_file = test::RunStrut(fmt::format("{} --channels {} -o {}", args, dir.file("channels.toml"),
                                                    dir.file("with.h5")));
  ASSERT_EQ(with_file.exit_code, 0) << with_file.output;
  const daq::Experiment wrong = daq::ReadSession(dir.file("without.h5")).experiments.at(0);
  const daq::Experiment right = daq::ReadSession(dir.file("with.h5")).experiments.at(0);
  EXPECT_LT(ForceMismatch(right, rig.plant).first, 25.0);
  // Read with the default gain, every force is 1.8311 / 2 of itself: 8.4 % of the swing off.
  const auto [mismatch, swing] = ForceMismatch(wrong, rig.plant);
  const double default_gain = daq::Calibration::FromRange16(-60e3, 60e3).gain;
  EXPECT_GT(mismatch, 0.5 * (1.0 - default_gain / 2.0) * swing);
  const auto& f_counts = wrong.channel("force_counts").samples;
  const auto& f_wrong = wrong.channel("force").samples;
  for (std::size_t i = 0; i < f_counts.size(); i += 17)
    EXPECT_NEAR(f_wrong[i], daq::Calibration::FromRange16(-60e3, 60e3).ToSi(static_cast<std::int32_t>(f_counts[i])), 1e-9);
}

TEST(RigRunCli, BadChannelFilesAreRefusedNamingTheFileLineAndKey) {
  TempDir dir;
  RemoteRig rig;
  const auto refused = [&](const std::string& text) {
    WriteFile(dir.file("c.toml"), text);
    const auto r = test::RunStrut(
        fmt::format("rig run {} --channels {} --serial S1 -o {}", rig.Args(), dir.file("c.toml"), dir.file("s.h5")));
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_FALSE(fs::exists(dir.file("s.h5")));
    return r.output;
  };
  const std::string f = dir.file("c.toml");
  const std::string ok_force = "[force]\nindex = 1\nunit = \"N\"\ngain = 2.0\n";
  // Each file, and what its refusal says.
  const std::pair<std::string, std::string> files[] = {
      {"frame = \"classic\"\n[stroke]\nindex = 0\nunit = \"m\"\ngain = 1e-5\n" + ok_force,
       f + ": module: the module number (0..63) is needed"},
      {"module = 1\nframe = \"classic\"\n[stroke]\nindex = 0\nunit = \"inch\"\ngain = 1e-5\n" + ok_force,
       f + ":5: [stroke] unit \"inch\": give one of m, mm"},
      {"module = 1\nframe = \"classic\"\n[stroke]\nindex = 1\nunit = \"m\"\ngain = 1e-5\n" + ok_force,
       f + ":8: [force] index 1 is [stroke]'s already"},
      {"module = 1\nframe = \"classic\"\n[stroke]\nindex = 4\nunit = \"m\"\ngain = 1e-5\n" + ok_force,
       f + ":2: classic frames of 5 readings per sample set"},
      {"module = 1\nframe = \"classic\"\nchannels = 2\n[stroke]\nindex = 2\nunit = \"m\"\ngain = 1e-5\n" + ok_force,
       f + ":5: [stroke] index 2 is beyond the 2 readings of a sample set"},
      {"module = 1\nframe = \"classic\"\n[stroke]\nindex = 0\nunit = \"m\"\ngian = 1e-5\n" + ok_force,
       f + ":6: [stroke] unknown key 'gian'"},
      {"module = 1\nframe = \"can\"\n[stroke]\nindex = 0\nunit = \"m\"\ngain = 1e-5\n" + ok_force,
       f + ":2: frame \"can\": give \"classic\" or \"fd\""},
      {"module = 1\nframe = \"classic\"\n[stroke]\nindex = 0\nunit = \"m\"\ngain = 1e-5\n", f + ": [force] is missing"},
      {"module = 1\nframe = \"classic\"\n[stroke]\nindex = 0\nunit = \"m\"\ngain = 0\n" + ok_force,
       f + ":6: [stroke] gain must not be zero"},
      {"module = 1\nframe = \"classic\"\n[stroke\nindex = 0\n", f + ":3:"},
  };
  for (const auto& [text, message] : files) {
    SCOPED_TRACE(text);
    EXPECT_NE(refused(text).find(message), std::string::npos);
  }
  // --rig sim has its own module.
  const auto sim = test::RunStrut(fmt::format("rig run --rig sim --channels {} -o {}", f, dir.file("s.h5")));
  EXPECT_EQ(sim.exit_code, 1);
  EXPECT_NE(sim.output.find("--channels " + f + ": with --rig sim the acquisition is the simulated rig's own"),
            std::string::npos)
      << sim.output;
}

}  // namespace
}  // namespace strut::rig
