// `strut rig serve-sim` as a process: it serves the simulated rig's controller over Modbus TCP and
// streams over CAN-over-UDP until SIGTERM, and refuses bad options naming them.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>

#include <chrono>
#include <fmt/format.h>
#include <string>
#include <thread>
#include <vector>

#include "strut/daq/can_acquisition.h"
#include "strut/sim/can_module.h"
#include "strut/sim/rig_server.h"
#include "strut/sim/truth.h"
#include "strut_cli.h"

namespace strut::sim {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

TEST(ServeSimCommand, ServesTheControllerAndStreamsUntilSigterm) {
  const int modbus = test::FreeLoopbackPort(SOCK_STREAM);
  auto receiver = daq::UdpCanTransport::Listen("127.0.0.1", 0);
  const std::string listen = fmt::format("127.0.0.1:{}", modbus);
  const std::string can = fmt::format("udp:127.0.0.1:{}", receiver->local_port());
  std::vector<std::string> args = {STRUT_BINARY, "rig", "serve-sim", "--listen", listen, "--can", can,
                                   "--speed", "5", "--seed", "3", "--log-interval", "0"};
  const pid_t pid = test::Spawn(args);
  ASSERT_GT(pid, 0);
  // The stream flows while the rig is idle, as a real acquisition's does.
  daq::CanAcquisition acquisition(std::move(receiver), [] {
    const Truth truth = DefaultTruth();
    daq::CanAcquisitionOptions o;
    o.layout.channels = 3;
    o.sample_rate = truth.acquisition.sample_rate * 5;  // --speed 5
    o.channels = CanChannels(truth.sensors);
    return o;
  }());
  acquisition.Start();
  std::size_t sets = 0;
  for (auto until = Clock::now() + 10s; sets < 200 && Clock::now() < until;) sets += acquisition.Read(50ms).size();
  EXPECT_GE(sets, 200u);
  const auto status = test::RunStrut("rig controller-status --json --modbus " + listen);
  EXPECT_EQ(status.exit_code, 0) << status.output;
  EXPECT_NE(status.output.find("\"state\": \"disarmed\""), std::string::npos) << status.output;
  ASSERT_EQ(kill(pid, SIGTERM), 0);
  int wstatus = 0;
  const auto signalled = Clock::now();
  pid_t done = 0;
  while ((done = waitpid(pid, &wstatus, WNOHANG)) == 0 && Clock::now() - signalled < 5s)
    std::this_thread::sleep_for(20ms);
  if (done == 0) kill(pid, SIGKILL), waitpid(pid, &wstatus, 0);
  ASSERT_EQ(done, pid) << "serve-sim did not stop within 5 s of SIGTERM";
  EXPECT_TRUE(WIFEXITED(wstatus) && WEXITSTATUS(wstatus) == 0);
}

TEST(ServeSimCommand, RefusesBadOptionsNamingThem) {
  const auto r = test::RunStrut("rig serve-sim --speed 0");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("--speed"), std::string::npos) << r.output;
  const auto busy = test::RunStrut("rig serve-sim --can bogus:1 --duration 1");
  EXPECT_NE(busy.exit_code, 0);
  EXPECT_NE(busy.output.find("bogus:1"), std::string::npos) << busy.output;
}

}  // namespace
}  // namespace strut::sim
