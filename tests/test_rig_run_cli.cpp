// `strut rig run` as a process (tools/cmd_rig_run.cpp, docs/rig-run.md) against a rig reachable from
// another process: the plant of tests/support/rig_plant.h served over Modbus TCP by
// daq::ModbusControllerServer in this test, its samples streamed as CAN frames over UDP. A matrix
// beyond the limits is refused before the rig moves; a run killed with SIGKILL mid-experiment and
// resumed with --resume completes the matrix into the same session file.
#include <gtest/gtest.h>
#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <spawn.h>
#include <spdlog/fmt/fmt.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include "rig_plant.h"
#include "strut/daq/can_transport.h"
#include "strut/daq/modbus_controller.h"
#include "strut/daq/recorder.h"
#include "strut/daq/session.h"
#include "test_support.h"

extern char** environ;

namespace strut::rig {
namespace {

using test::Plant;
using test::PlantOptions;
using test::TempDir;
namespace fs = std::filesystem;

// A UDP port free at the moment (the runner listens there; the plant's module sends to it).
int FreeUdpPort() {
  const int fd = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
  socklen_t n = sizeof a;
  getsockname(fd, reinterpret_cast<sockaddr*>(&a), &n);
  close(fd);
  return ntohs(a.sin_port);
}

// The rig of another process: the plant's controller over Modbus TCP, its module over UDP.
struct RemoteRig {
  explicit RemoteRig(PlantOptions o = {}) : plant(o), server(plant), udp_port(FreeUdpPort()) {
    streamer = std::make_unique<test::PlantCanStreamer>(
        plant, daq::UdpCanTransport::Connect("127.0.0.1", static_cast<std::uint16_t>(udp_port)));
  }
  std::string Args() const {
    // --drift-window 0: the plant has no thermal drift and the test runs in real time.
    return fmt::format("--rig modbus-tcp://127.0.0.1:{} --daq udp:127.0.0.1:{} --daq-rate {} --drift-window 0", server.port(), udp_port,
                       plant.options().sample_rate);
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
  EXPECT_NE(r.output.find("experiment 'deep': stroke 0.22 .. 0.28 m leaves the stroke limit -0.005 .. 0.26 m"),
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

pid_t Spawn(const std::string& command_line) {
  std::vector<std::string> args{"/bin/sh", "-c", "exec " + command_line};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = -1;
  if (posix_spawn(&pid, argv[0], nullptr, nullptr, argv.data(), environ) != 0) return -1;
  return pid;
}

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
  const pid_t pid = Spawn(common + " --serial K9 --no-progress > " + dir.file("first.log") + " 2>&1");
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

}  // namespace
}  // namespace strut::rig
