// The actuator controller over Modbus TCP on loopback: strut's client against strut's server
// with the fake backend, and against a scripted peer that misbehaves (slow, stalling, gone).
#include <gtest/gtest.h>
#include <modbus/modbus.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <optional>
#include <random>
#include <thread>

#include "modbus_test_peer.h"
#include "set_points.h"
#include "strut/daq/fake_controller.h"
#include "strut/daq/modbus_controller.h"

namespace strut::daq {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;
namespace reg = registers;

ModbusControllerOptions Options(int port) {
  ModbusControllerOptions o;
  o.endpoint = {"127.0.0.1", port};
  o.response_timeout = 500ms;
  o.byte_timeout = 100ms;
  o.reconnect_initial = 20ms;
  o.reconnect_max = 160ms;
  return o;
}

// A fake controller served on loopback and a client of it, made and destroyed in that order.
struct Loopback {
  FakeControllerBackend backend;
  ModbusControllerServer server{backend};
  ModbusController client{Options(server.port())};
};

SetPoint Typical() { return strut::test::ExperimentHSetPoint(/*ramp_cycles=*/2); }

double F32(double v) {  // see test_modbus_registers.cpp for why volatile
  volatile float f = static_cast<float>(v);
  return f;
}

double Seconds(Clock::time_point since) { return std::chrono::duration<double>(Clock::now() - since).count(); }

//! Runs `call`, expects a DeviceError of `kind`, and returns it.
template <class F>
DeviceError Expect(DeviceError::Kind kind, F call) {
  try {
    call();
  } catch (const DeviceError& e) {
    EXPECT_EQ(e.kind(), kind) << e.what();
    return e;
  }
  ADD_FAILURE() << "no DeviceError";
  return DeviceError(kind, "", "", "", 0, "");
}

TEST(ModbusEndpoint, ParsesHostPortFormsAndRefusesBadOnes) {
  EXPECT_EQ(ParseModbusEndpoint("127.0.0.1:1502").port, 1502);
  EXPECT_EQ(ParseModbusEndpoint("modbus-tcp://rig.lab:502").host, "rig.lab");
  EXPECT_EQ(ParseModbusEndpoint("[::1]:1502").host, "::1");
  EXPECT_EQ(ParseModbusEndpoint("[::1]:1502").ToString(), "modbus-tcp://[::1]:1502");
  for (const char* bad : {"127.0.0.1", "127.0.0.1:0", "127.0.0.1:70000", ":502", "host:x", "[::1]1502"}) {
    try {
      ParseModbusEndpoint(bad);
      ADD_FAILURE() << bad;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
    }
  }
}

TEST(ModbusController, EveryRegisterRoundTrips) {
  Loopback loopback;
  auto& [backend, server, client] = loopback;

  // Holding registers 0-19: the set-point block, as the client encodes it and the backend gets it.
  SetPoint s = Typical();
  s.mode = ControlMode::kForce;
  s.static_position = -1234.5;
  s.amplitude = 2.0e4;
  s.frequency = 7.25;
  s.ramp_cycles = 17;
  s.static_rate = 2.5e3;
  s.limits = {-0.002, 0.3375, -3.0e4, 4.0e4};
  const std::uint16_t sequence = client.WriteSetPoint(s);
  EXPECT_EQ(sequence, 1);
  const auto holding = client.ReadHoldingRegisters(0, reg::holding::kCount);
  const reg::SetPointBlock expected = reg::EncodeSetPoint(s, sequence);
  for (std::uint16_t a = 0; a < reg::holding::kSetPointCount; ++a)
    EXPECT_EQ(holding[a], expected[a]) << reg::HoldingName(a);
  SetPoint rounded = s;
  rounded.static_position = F32(s.static_position);
  rounded.frequency = F32(s.frequency);
  rounded.limits = {F32(s.limits.stroke_min), F32(s.limits.stroke_max), s.limits.force_min, s.limits.force_max};
  ASSERT_EQ(backend.applied().size(), 1u);
  EXPECT_EQ(backend.applied().back(), rounded);
  EXPECT_EQ(client.ReadSetPoint(), rounded);

  // Holding registers 20-22: command, client heartbeat, watchdog.
  client.Arm();
  client.Heartbeat();
  client.Heartbeat();
  client.SetWatchdog(1234ms);
  const auto tail = client.ReadHoldingRegisters(reg::holding::kCommand, 3);
  EXPECT_EQ(tail[0], static_cast<std::uint16_t>(ControllerCommand::kArm));
  EXPECT_EQ(tail[1], 2);
  EXPECT_EQ(tail[2], 1234);
  client.SetWatchdog(0ms);

  // Input registers 0-15: every field of the status with a distinct value.
  ControllerStatus st;
  st.state = ControllerState::kStopping;
  st.mode = ControlMode::kForce;
  st.status_word = status_bits::kHydraulicsOn | status_bits::kRamping;
  st.fault_word = fault_bits::kFollowingError;
  st.stroke = 0.1875;
  st.force = -12345.5;
  st.command = 2.0e4;
  st.cycles = 123456;
  st.time_ms = 3000000001u;
  backend.SetStatus(st, true);
  const ControllerStatus got = client.ReadStatus();
  EXPECT_EQ(got.state, st.state);
  EXPECT_EQ(got.mode, st.mode);
  EXPECT_EQ(got.status_word, st.status_word);
  EXPECT_EQ(got.fault_word, st.fault_word);
  EXPECT_EQ(got.applied_sequence, sequence);  // the server's, not the backend's
  EXPECT_EQ(got.stroke, st.stroke);
  EXPECT_EQ(got.force, st.force);
  EXPECT_EQ(got.command, st.command);
  EXPECT_EQ(got.cycles, st.cycles);
  EXPECT_EQ(got.time_ms, st.time_ms);
  // The heartbeat counts server ticks (10 ms).
  std::this_thread::sleep_for(100ms);
  const std::uint16_t later = client.ReadStatus().heartbeat;
  EXPECT_GE(static_cast<std::uint16_t>(later - got.heartbeat), 3) << got.heartbeat << " then " << later;
  // Input registers 16-49: the refusal block (empty until something is refused).
  const auto refusal = client.ReadInputRegisters(reg::input::kRefusalBlock, reg::input::kRefusalCount);
  EXPECT_EQ(refusal[0], 0);
}

TEST(ModbusController, HalfWrittenSetPointIsNeverApplied) {
  Loopback loopback;
  auto& [backend, server, client] = loopback;
  const std::uint16_t first = client.WriteSetPoint(Typical());
  ASSERT_EQ(backend.applied().size(), 1u);

  SetPoint next = Typical();
  next.amplitude = 0.05;
  const reg::SetPointBlock block = reg::EncodeSetPoint(next, static_cast<std::uint16_t>(first + 1));
  // 1. The block's values without the commit register: staged, not applied.
  client.WriteHoldingRegisters(0, std::span(block.data(), 18));
  EXPECT_EQ(backend.applied().size(), 1u);
  EXPECT_EQ(client.ReadStatus().applied_sequence, first);
  // 2. A new sequence with a checksum that does not match what is staged: refused, as an exception.
  reg::SetPointBlock torn = block;
  torn[reg::holding::kAmplitude] ^= 0x0040;  // a register that did not arrive as meant
  const DeviceError e = Expect(DeviceError::Kind::kRefused, [&] {
    client.WriteHoldingRegisters(reg::holding::kAmplitude, std::span(torn.data() + reg::holding::kAmplitude, 2));
    client.WriteHoldingRegisters(reg::holding::kChecksum, std::span(block.data() + reg::holding::kChecksum, 2));
  });
  EXPECT_NE(std::string(e.what()).find("checksum"), std::string::npos) << e.what();
  EXPECT_NE(std::string(e.what()).find("holding register 18"), std::string::npos) << e.what();
  EXPECT_EQ(backend.applied().size(), 1u);
  EXPECT_EQ(client.ReadStatus().applied_sequence, first);
  // 3. A request cut off by a dying connection: the server drops it; nothing is written.
  std::vector<std::uint8_t> adu = {0x00, 0x07, 0x00, 0x00, 0x00, 47, 0x01, 0x10, 0x00, 0x00, 0x00, 20, 40};
  for (int i = 0; i < 10; ++i) {  // only 10 of the 20 registers
    adu.push_back(static_cast<std::uint8_t>(block[i] >> 8));
    adu.push_back(static_cast<std::uint8_t>(block[i] & 0xFF));
  }
  ASSERT_TRUE(test::SendRawAndClose(server.port(), adu));
  EXPECT_EQ(backend.applied().size(), 1u);
  EXPECT_EQ(client.ReadHoldingRegisters(reg::holding::kAmplitude, 2)[0], torn[reg::holding::kAmplitude]);
  // 4. The whole block in one request applies it.
  EXPECT_EQ(client.WriteSetPoint(next), first + 1);
  ASSERT_EQ(backend.applied().size(), 2u);
  EXPECT_EQ(backend.applied().back().amplitude, F32(0.05));
  EXPECT_EQ(client.ReadStatus().applied_sequence, first + 1);
  // 5. The same sequence again (a retry after a lost answer) is not applied twice.
  client.WriteHoldingRegisters(0, reg::EncodeSetPoint(next, static_cast<std::uint16_t>(first + 1)));
  EXPECT_EQ(backend.applied().size(), 2u);
}

TEST(ModbusController, RefusedCommandArrivesAsAnExceptionWithTheControllersReason) {
  Loopback loopback;
  auto& [backend, server, client] = loopback;
  client.WriteSetPoint(Typical());
  const DeviceError e = Expect(DeviceError::Kind::kRefused, [&] { client.Run(); });
  const std::string what = e.what();
  EXPECT_EQ(e.error_number(), EMBXILVAL);
  EXPECT_NE(what.find("Illegal data value"), std::string::npos) << what;  // modbus_strerror's text
  EXPECT_NE(what.find("not armed"), std::string::npos) << what;          // the backend's reason
  EXPECT_NE(what.find("holding register 20 (command)"), std::string::npos) << what;
  EXPECT_EQ(server.refusals(), 1);
  client.Arm();
  client.Run();
  EXPECT_EQ(client.ReadStatus().state, ControllerState::kRunning);
  // A mode change while running is refused by the backend; the set-point stays as it was.
  SetPoint force = Typical();
  force.mode = ControlMode::kForce;
  force.static_position = 0;
  force.amplitude = 1e4;
  const DeviceError mode = Expect(DeviceError::Kind::kRefused, [&] { client.WriteSetPoint(force); });
  EXPECT_NE(std::string(mode.what()).find("while running"), std::string::npos) << mode.what();
  EXPECT_EQ(backend.applied().size(), 1u);
  client.Stop();
  EXPECT_EQ(client.ReadStatus().state, ControllerState::kArmed);
  // An unknown command code, written raw.
  const std::uint16_t nine = 9;
  const DeviceError unknown = Expect(DeviceError::Kind::kRefused, [&] {
    client.WriteHoldingRegisters(reg::holding::kCommand, std::span(&nine, 1));
  });
  EXPECT_NE(std::string(unknown.what()).find("names no command"), std::string::npos) << unknown.what();
}

TEST(ModbusController, AddressOutsideTheMapIsAnExceptionAndTheConnectionStays) {
  Loopback loopback;
  auto& [backend, server, client] = loopback;
  const DeviceError e = Expect(DeviceError::Kind::kRefused, [&] { client.ReadHoldingRegisters(20, 10); });
  EXPECT_EQ(e.error_number(), EMBXILADD);
  EXPECT_NE(std::string(e.what()).find("holding registers 20-29"), std::string::npos) << e.what();
  EXPECT_NE(std::string(e.what()).find("Illegal data address"), std::string::npos) << e.what();
  const std::uint16_t one = 1;
  Expect(DeviceError::Kind::kRefused, [&] { client.WriteHoldingRegisters(reg::holding::kCount, std::span(&one, 1)); });
  EXPECT_EQ(client.ReadStatus().state, ControllerState::kDisarmed);
  EXPECT_EQ(client.stats().connect_attempts, 1);
}

TEST(ModbusController, InvalidSetPointIsRefusedBeforeSendingAndNaNWrittenRawIsRefusedByTheServer) {
  Loopback loopback;
  auto& [backend, server, client] = loopback;
  client.ReadStatus();
  const long requests = server.requests();
  SetPoint bad = Typical();
  bad.amplitude = std::numeric_limits<double>::quiet_NaN();
  const DeviceError local = Expect(DeviceError::Kind::kInvalidValue, [&] { client.WriteSetPoint(bad); });
  EXPECT_NE(std::string(local.what()).find("amplitude is nan"), std::string::npos) << local.what();
  EXPECT_EQ(server.requests(), requests);  // not sent

  reg::SetPointBlock block = reg::EncodeSetPoint(Typical(), 1);
  reg::PutFloat(std::span<std::uint16_t, 2>(&block[reg::holding::kAmplitude], 2), NAN);
  block[reg::holding::kChecksum] = reg::SetPointChecksum(block);
  const DeviceError remote = Expect(DeviceError::Kind::kRefused, [&] { client.WriteHoldingRegisters(0, block); });
  EXPECT_NE(std::string(remote.what()).find("holding register 4 (amplitude)"), std::string::npos) << remote.what();
  EXPECT_NE(std::string(remote.what()).find("not a finite number"), std::string::npos) << remote.what();
  EXPECT_TRUE(backend.applied().empty());
}

TEST(ModbusController, SlowPeerHitsTheResponseTimeoutInAboutTheConfiguredTime) {
  for (const auto timeout : {150ms, 400ms}) {
    // Answers the connect's read of the applied sequence and one more read, then falls silent.
    test::ScriptedModbusPeer peer(2, test::ScriptedModbusPeer::Misbehaviour::kSilent);
    ModbusControllerOptions options = Options(peer.port());
    options.response_timeout = timeout;
    options.byte_timeout = 50ms;
    ModbusController client(options);
    client.ReadInputRegisters(0, 1);  // connected: the peer answered the first request
    const auto start = Clock::now();
    const DeviceError e = Expect(DeviceError::Kind::kTimeout, [&] { client.ReadStatus(); });
    const double elapsed = Seconds(start);
    const double configured = std::chrono::duration<double>(timeout).count();
    EXPECT_GE(elapsed, 0.9 * configured) << e.what();
    EXPECT_LT(elapsed, configured + 0.35) << e.what();
    EXPECT_NE(std::string(e.what()).find("input registers 0-15 (status block)"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("Connection timed out"), std::string::npos) << e.what();
    EXPECT_GE(client.stats().flushes, 1);  // modbus_flush after the timeout
    EXPECT_EQ(client.stats().timeouts, 1);
  }
}

TEST(ModbusController, LateAnswerAfterATimeoutIsNotTakenForTheNextAnswer) {
  // The third request is answered 300 ms late; the client gives up after 150 ms.
  test::ScriptedModbusPeer peer(2, test::ScriptedModbusPeer::Misbehaviour::kLate, 300ms, 1);
  ModbusControllerOptions options = Options(peer.port());
  options.response_timeout = 150ms;
  ModbusController client(options);
  client.ReadInputRegisters(0, 1);
  Expect(DeviceError::Kind::kTimeout, [&] { client.ReadInputRegisters(0, 16); });
  std::this_thread::sleep_for(300ms);  // the late 16-register answer is now waiting in the socket
  // The next request gets its own answer (5 registers), not the late one.
  EXPECT_EQ(client.ReadInputRegisters(0, 5).size(), 5u);
  EXPECT_EQ(client.ReadInputRegisters(0, 7).size(), 7u);
  EXPECT_GE(client.stats().flushes, 2);
}

TEST(ModbusController, PeerStallingMidAnswerHitsTheByteTimeout) {
  test::ScriptedModbusPeer peer(2, test::ScriptedModbusPeer::Misbehaviour::kStallMidAnswer);
  ModbusControllerOptions options = Options(peer.port());
  options.response_timeout = 3000ms;
  options.byte_timeout = 120ms;
  ModbusController client(options);
  client.ReadInputRegisters(0, 1);
  const auto start = Clock::now();
  const DeviceError e = Expect(DeviceError::Kind::kTimeout, [&] { client.ReadStatus(); });
  const double elapsed = Seconds(start);
  EXPECT_GE(elapsed, 0.1) << e.what();
  EXPECT_LT(elapsed, 1.0) << e.what();  // the byte timeout, far below the 3 s response timeout
}

TEST(ModbusController, ServerDisappearingFailsFastAndReconnectsWithCappedBackoff) {
  FakeControllerBackend backend;
  auto server = std::make_unique<ModbusControllerServer>(backend);
  const int port = server->port();
  ModbusController client(Options(port));
  client.WriteSetPoint(Typical());
  EXPECT_TRUE(client.stats().connected);

  server.reset();  // the controller goes away mid-run
  auto start = Clock::now();
  const DeviceError lost = Expect(DeviceError::Kind::kConnection, [&] { client.ReadStatus(); });
  EXPECT_LT(Seconds(start), 1.0) << lost.what();
  EXPECT_NE(std::string(lost.what()).find("modbus-tcp://127.0.0.1:" + std::to_string(port)), std::string::npos);
  // While it is away, calls fail at once and say when the next attempt is.
  std::this_thread::sleep_for(50ms);
  start = Clock::now();
  const DeviceError away = Expect(DeviceError::Kind::kConnection, [&] { client.ReadStatus(); });
  EXPECT_LT(Seconds(start), 0.6) << away.what();
  EXPECT_NE(std::string(away.what()).find("Connection refused"), std::string::npos) << away.what();
  // The I/O thread keeps trying in the background: 20, 40, 80, 160, 160, ... ms.
  std::this_thread::sleep_for(1000ms);
  const ModbusConnectionStats stats = client.stats();
  ASSERT_GE(stats.backoffs.size(), 5u);
  EXPECT_EQ(stats.backoffs[0], 20ms);
  EXPECT_EQ(stats.backoffs[1], 40ms);
  EXPECT_EQ(stats.backoffs[2], 80ms);
  for (std::size_t i = 3; i < stats.backoffs.size(); ++i) EXPECT_EQ(stats.backoffs[i], 160ms);
  // About 1 s / 160 ms attempts, far fewer than a fixed 20 ms retry would make.
  EXPECT_LE(stats.connect_failures, 16);

  FakeControllerBackend backend2;
  ModbusServerOptions again;
  again.port = port;
  ModbusControllerServer back(backend2, again);
  start = Clock::now();
  bool reconnected = false;
  while (Seconds(start) < 3.0 && !reconnected) {
    try {
      client.ReadStatus();
      reconnected = true;
    } catch (const DeviceError&) {
      std::this_thread::sleep_for(20ms);
    }
  }
  EXPECT_TRUE(reconnected);
  EXPECT_LT(Seconds(start), 0.5);  // within one capped backoff
  // The new controller has applied nothing: the client's next set-point is sequence 1 there.
  EXPECT_EQ(client.WriteSetPoint(Typical()), 1);
  EXPECT_EQ(backend2.applied().size(), 1u);
}

TEST(ModbusController, LostHeartbeatStopsTheControllerAndLatchesAFault) {
  Loopback loopback;
  auto& [backend, server, client] = loopback;
  client.WriteSetPoint(Typical());
  client.Arm();
  client.Run();
  client.SetWatchdog(150ms);
  for (int i = 0; i < 8; ++i) {
    client.Heartbeat();
    std::this_thread::sleep_for(40ms);
  }
  ControllerStatus st = client.ReadStatus();
  EXPECT_EQ(st.state, ControllerState::kRunning);
  EXPECT_EQ(st.fault_word, 0);
  EXPECT_TRUE(st.status_word & status_bits::kWatchdogEnabled);
  std::this_thread::sleep_for(400ms);  // the runner stops beating
  st = client.ReadStatus();
  EXPECT_TRUE(st.fault_word & fault_bits::kHeartbeatLost) << FaultBitsText(st.fault_word);
  EXPECT_EQ(st.state, ControllerState::kArmed);  // stopped: back at the static level
  EXPECT_EQ(backend.commands().back(), ControllerCommand::kStop);
  client.SetWatchdog(0ms);
  client.ResetFaults();
  EXPECT_EQ(client.ReadStatus().fault_word, 0);
}

TEST(ModbusController, CallsFromManyThreadsAreServedByTheOneIoOwner) {
  Loopback loopback;
  auto& [backend, server, client] = loopback;
  client.WriteSetPoint(Typical());
  std::atomic<int> ok{0}, failed{0};
  std::vector<std::thread> threads;
  const auto start = Clock::now();
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&, t] {
      for (int i = 0; i < 100; ++i) {
        try {
          if (t == 0)
            client.Heartbeat();
          else
            client.ReadStatus();
          ++ok;
        } catch (const DeviceError&) {
          ++failed;
        }
      }
    });
  for (auto& t : threads) t.join();
  std::printf("400 calls from 4 threads in %.3f s\n", Seconds(start));
  EXPECT_EQ(ok, 400);
  EXPECT_EQ(failed, 0);
  EXPECT_EQ(client.ReadHoldingRegisters(reg::holding::kClientHeartbeat, 1)[0], 100);
  EXPECT_EQ(client.stats().connect_attempts, 1);
}

TEST(ModbusController, NewClientContinuesAfterTheAppliedSequence) {
  FakeControllerBackend backend;
  ModbusControllerServer server(backend);
  {
    ModbusController first(Options(server.port()));
    for (int i = 0; i < 3; ++i) first.WriteSetPoint(Typical());
  }
  ModbusController second(Options(server.port()));
  EXPECT_EQ(second.WriteSetPoint(Typical()), 4);
  EXPECT_EQ(backend.applied().size(), 4u);
}

TEST(ModbusControllerServer, GarbageFromTheNetworkNeitherCrashesNorAppliesAnything) {
  FakeControllerBackend backend;
  ModbusServerOptions options;
  options.byte_timeout = 10ms;
  ModbusControllerServer server(backend, options);
  std::mt19937 rng(13);
  std::uniform_int_distribution<int> byte(0, 255);
  for (int i = 0; i < 40; ++i) {
    std::vector<std::uint8_t> adu(static_cast<std::size_t>(1 + byte(rng) % 40));
    for (auto& b : adu) b = static_cast<std::uint8_t>(byte(rng));
    if (i % 2 == 0 && adu.size() >= 8) {  // a plausible MBAP header with a random PDU
      adu[2] = adu[3] = 0;
      adu[4] = 0;
      adu[5] = static_cast<std::uint8_t>(adu.size() - 6);
      adu[7] = static_cast<std::uint8_t>(std::array{3, 4, 6, 16, 1, 23, 43}[static_cast<std::size_t>(i / 2 % 7)]);
    }
    ASSERT_TRUE(test::SendRawAndClose(server.port(), adu, 5ms));
  }
  // The server works through the queued connections one at a time (each may hold it for its
  // byte timeout); then it serves a proper client again.
  ModbusController client(Options(server.port()));
  std::optional<ControllerStatus> status;
  for (const auto start = Clock::now(); !status && Seconds(start) < 20.0;) {
    try {
      status = client.ReadStatus();
    } catch (const DeviceError&) {
      std::this_thread::sleep_for(50ms);
    }
  }
  ASSERT_TRUE(status.has_value());
  EXPECT_EQ(status->applied_sequence, 0);
  EXPECT_TRUE(backend.applied().empty());
  EXPECT_TRUE(backend.commands().empty());
  EXPECT_EQ(client.WriteSetPoint(Typical()), 1);
}

TEST(ModbusControllerServer, FailingBackendIsReportedAsADeviceFault) {
  Loopback loopback;
  auto& [backend, server, client] = loopback;
  backend.FailStatus(true);
  std::this_thread::sleep_for(30ms);
  const ControllerStatus st = client.ReadStatus();
  EXPECT_EQ(st.state, ControllerState::kFaulted);
  EXPECT_TRUE(st.fault_word & fault_bits::kDevice) << FaultBitsText(st.fault_word);
}

TEST(ModbusControllerServer, BindsOneIpv4AddressAndNamesItWhenItCannot) {
  FakeControllerBackend backend;
  EXPECT_THROW(ModbusControllerServer(backend, {.host = "localhost"}), std::invalid_argument);
  ModbusControllerServer first(backend);
  EXPECT_EQ(first.endpoint().host, "127.0.0.1");
  ModbusServerOptions same;
  same.port = first.port();
  try {
    ModbusControllerServer second(backend, same);
    ADD_FAILURE() << "a second server on the same port";
  } catch (const DeviceError& e) {
    EXPECT_NE(std::string(e.what()).find("127.0.0.1:" + std::to_string(first.port())), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("Address already in use"), std::string::npos) << e.what();
  }
}

TEST(ModbusController, UnreachableControllerIsAClearConnectionError) {
  int port;
  {
    FakeControllerBackend backend;
    ModbusControllerServer gone(backend);
    port = gone.port();
  }
  ModbusController client(Options(port));
  const auto start = Clock::now();
  const DeviceError e = Expect(DeviceError::Kind::kConnection, [&] { client.ReadStatus(); });
  EXPECT_LT(Seconds(start), 1.0);
  EXPECT_NE(std::string(e.what()).find("Connection refused"), std::string::npos) << e.what();
}

}  // namespace
}  // namespace strut::daq
