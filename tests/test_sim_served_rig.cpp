// The simulated rig behind the real protocols, end to end over loopback (issue 13's proof): a
// sim::RigServer in-process on ephemeral ports; a client of the real drivers (daq::ModbusController
// and daq::CanAcquisition over UDP) sets up, arms and runs experiment j, waits for steady state,
// records whole periods through the streaming Recorder and compares the file with what sim/ writes
// directly (SimulatedRig::RunPeriodic) for the same truth. Then the faults, each ending in a clear
// condition within a bounded time: the controller going away mid-run, a frozen stream, a Modbus
// exception, a limit trip mid-sine. (`strut rig serve-sim` as a process: test_rig_serve_sim_cli.cpp.)
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <complex>
#include <fmt/format.h>
#include <functional>
#include <numbers>
#include <thread>

#include "strut/daq/can_acquisition.h"
#include "strut/daq/modbus_controller.h"
#include "strut/daq/recorder.h"
#include "strut/daq/rig_devices.h"
#include "strut/daq/session.h"
#include "strut/sim/rig_server.h"
#include "strut/sim/simulated_rig.h"
#include "test_support.h"

namespace strut::sim {
namespace {

using namespace std::chrono_literals;
using daq::ControllerState;
using daq::DeviceError;
using daq::Quality;
using Clock = std::chrono::steady_clock;
namespace status_bits = daq::status_bits;
namespace fault_bits = daq::fault_bits;

// Experiment j of the standard matrix: 2 Hz, 10 mm about 133 mm.
const rig::MatrixEntry kJ{"j", "middle", 2.0, 0.133, 0.010};

daq::SetPoint SetPointJ() {
  daq::SetPoint sp;
  sp.static_position = kJ.static_position;
  sp.amplitude = kJ.amplitude;
  sp.frequency = kJ.frequency;
  sp.ramp_cycles = 2;
  sp.static_rate = 0.02;
  return sp;
}

//! A served rig and a client of the real drivers. The test's thread owns the acquisition.
struct Loopback {
  std::unique_ptr<RigServer> server;
  std::unique_ptr<daq::ModbusController> controller;
  std::unique_ptr<daq::CanAcquisition> acquisition;
  std::vector<daq::AcquiredBlock> blocks;  //!< what Pump read while nobody consumed it

  explicit Loopback(double initial_stroke, double speed = 10.0, bool fd = false) {
    auto receiver = daq::UdpCanTransport::Listen("127.0.0.1", 0);
    RigServerOptions o;
    o.can_fd = fd;
    o.can = fmt::format("udp:127.0.0.1:{}", receiver->local_port());
    o.speed = speed;
    o.controller.initial_stroke = initial_stroke;
    server = std::make_unique<RigServer>(DefaultTruth(), o);
    acquisition = std::make_unique<daq::CanAcquisition>(std::move(receiver), server->ReceiverOptions());
    acquisition->Start();
    daq::ModbusControllerOptions c;
    c.endpoint = server->modbus_endpoint();
    controller = std::make_unique<daq::ModbusController>(c);
    server->Start();
  }

  //! Reads the stream and polls the status until `done` says so; false after `timeout`.
  bool WaitFor(const std::function<bool(const daq::ControllerStatus&)>& done, Clock::duration timeout) {
    const auto deadline = Clock::now() + timeout;
    while (Clock::now() < deadline) {
      daq::AcquiredBlock b = acquisition->Read(20ms);
      if (!b.empty()) blocks.push_back(std::move(b));
      if (done(controller->ReadStatus())) return true;
    }
    return false;
  }
};

//! Harmonics 0..K of x against the stroke's fundamental phase: c_k e^{-i k phi}, where the stroke
//! is mean + A sin(w t + phi). Phase-aligned, so two records starting anywhere compare.
struct Harmonics {
  std::vector<std::complex<double>> force, pressure;
};
Harmonics AlignedHarmonics(const daq::Experiment& e, int K) {
  const auto& y = e.channel("stroke").samples;
  const double w = 2 * std::numbers::pi * e.frequency, n = static_cast<double>(y.size());
  const auto coefficient = [&](const std::vector<double>& x, int k) {
    std::complex<double> c = 0;
    for (std::size_t i = 0; i < x.size(); ++i) c += x[i] * std::polar(1.0, -k * w * i / e.sample_rate);
    return c * (k == 0 ? 1.0 : 2.0) / n;
  };
  // sin(wt + phi) has the coefficient -i e^{i phi}.
  const double phi = std::arg(coefficient(y, 1) * std::complex<double>(0, 1));
  Harmonics h;
  for (int k = 0; k <= K; ++k) {
    const std::complex<double> turn = std::polar(1.0, -k * phi);
    h.force.push_back(coefficient(e.channel("force").samples, k) * turn);
    h.pressure.push_back(coefficient(e.channel("pressure").samples, k) * turn);
  }
  return h;
}
//! The period-averaged waveform from harmonics at phase theta.
double Waveform(const std::vector<std::complex<double>>& c, double theta) {
  double v = c[0].real();
  for (std::size_t k = 1; k < c.size(); ++k) v += (c[k] * std::polar(1.0, k * theta)).real();
  return v;
}

TEST(ServedRig, RecordsAnExperimentOverModbusAndCanThatMatchesTheSimulatedRig) {
  test::TempDir dir;
  const std::string path = dir.file("served.h5");
  const auto wall_start = Clock::now();
  // The piston rests at the static position with the gas at ambient: a move there first would heat
  // the gas, and its 18 s thermal time constant (docs/simulated-rig.md) would then need minutes of
  // sine to settle where SimulatedRig starts from the periodic solution.
  Loopback rig(kJ.static_position);
  // Set up, arm, wait at the static level, run, wait for the full amplitude and four more cycles
  // (the test's own steady-state rule; the runner's detector is issue 14's).
  rig.controller->WriteSetPoint(SetPointJ());
  rig.controller->Arm();
  ASSERT_TRUE(rig.WaitFor([](const auto& s) { return (s.status_word & status_bits::kAtStatic) != 0; }, 10s));
  rig.controller->Run();
  ASSERT_TRUE(rig.WaitFor(
      [](const auto& s) { return (s.status_word & status_bits::kFullAmplitude) != 0 && s.cycles >= 6; }, 15s));

  // Record five whole periods (500 sample sets at 200 Hz) through the recorder.
  constexpr long kPeriods = 5;
  const std::size_t wanted = kPeriods * 100;
  {
    daq::RecordingMetadata meta;
    meta.damper_serial = "SIM-F16N-0001";
    meta.rig = "strut rig serve-sim (in-process, loopback)";
    auto recorder = daq::Recorder::Open(path, meta);
    // The file states the simulated rate, and the timestamps go on the simulated clock.
    const daq::Experiment header = rig::PeriodicExperimentOf(kJ, kPeriods, rig.server->simulated_sample_rate());
    recorder.BeginExperiment(daq::AcquiredExperiment(header, rig.acquisition->description()));
    rig.blocks.clear();  // start with fresh samples
    std::size_t recorded = 0;
    std::optional<std::int64_t> origin;
    const auto deadline = Clock::now() + 20s;
    while (recorded < wanted) {
      ASSERT_LT(Clock::now(), deadline) << "the stream did not deliver " << wanted << " samples";
      const daq::AcquiredBlock b = rig.acquisition->Read(50ms);
      if (b.empty()) continue;
      ASSERT_TRUE(b.quality.valid()) << b.quality.ToString();
      ASSERT_FALSE(recorded > 0 && b.lost_before > 0) << "sample sets lost mid-record";
      const std::size_t take = std::min(b.size(), wanted - recorded);
      daq::SampleBlock block = daq::RecordedBlock(b, 0, take);
      if (!origin) origin = block.monotonic_ns.front();
      daq::ToRecordedTime(block, *origin, rig.server->options().speed);
      recorder.Append(block);
      recorded += take;
    }
    recorder.EndExperiment(daq::EndStatus::kComplete, kPeriods);
    recorder.Close();
  }
  rig.controller->Stop();
  EXPECT_TRUE(rig.WaitFor([](const auto& s) { return s.state == ControllerState::kArmed; }, 10s));
  rig.controller->Disarm();
  const RigServerStats stats = rig.server->stats();
  rig.server->Stop();
  EXPECT_FALSE(rig.server->error());
  EXPECT_EQ(rig.acquisition->stats().lost_sample_sets, 0u);
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - wall_start).count(), 30.0);
  std::printf("served %.1f simulated s in %.1f wall s (speed 10), plant %.2f CPU s, late at most %.3f s\n",
              stats.simulated_seconds, stats.wall_seconds, stats.compute_seconds, stats.max_lateness);

  // The contract check, then the comparison with what sim/ writes directly for the same truth.
  const daq::Session served = daq::ReadSession(path);
  ASSERT_EQ(served.experiments.size(), 1u);
  const daq::Experiment& e = served.experiments[0];
  EXPECT_EQ(e.status, "complete");
  EXPECT_EQ(e.periods, kPeriods);
  ASSERT_EQ(e.sample_count(), static_cast<long>(wanted));
  EXPECT_EQ(e.channel("pressure").reference, "gauge");
  const SimulatedRig direct(DefaultTruth());
  std::mt19937_64 rng(11);
  // At the served stream's sampling phases (its sine starts at phase 0 on a sample): friction's
  // sharp reversals alias differently at other phases (some 50 N between two direct runs).
  const daq::Experiment reference = direct.RunPeriodic(kJ, 200.0, kPeriods, rng, nullptr, nullptr, {}, 0.0);
  const int K = 20;
  const Harmonics a = AlignedHarmonics(e, K), b = AlignedHarmonics(reference, K);
  // Noise of a waveform point rebuilt from 2K + 1 coefficients of N samples: sd sqrt((2K+1)/N),
  // and the difference of two records sqrt(2) of that. Allow five of them.
  const Truth truth = DefaultTruth();
  const double spread = std::sqrt(2.0 * (2 * K + 1) / static_cast<double>(wanted));
  const double force_tolerance = 5 * spread * truth.sensors.force.noise;
  const double pressure_tolerance = 5 * spread * truth.sensors.pressure.noise;
  double worst_force = 0, worst_pressure = 0;
  for (int bin = 0; bin < 40; ++bin) {
    const double theta = 2 * std::numbers::pi * (bin + 0.5) / 40;
    const double df = Waveform(a.force, theta) - Waveform(b.force, theta);
    const double dp = Waveform(a.pressure, theta) - Waveform(b.pressure, theta);
    EXPECT_LT(std::abs(df), force_tolerance) << "force, phase bin " << bin;
    EXPECT_LT(std::abs(dp), pressure_tolerance) << "pressure, phase bin " << bin;
    worst_force = std::max(worst_force, std::abs(df));
    worst_pressure = std::max(worst_pressure, std::abs(dp));
  }
  std::printf("served vs direct, 40 phase bins: force within %.1f N (tolerance %.1f N), pressure within %.0f Pa "
              "(tolerance %.0f Pa)\n",
              worst_force, force_tolerance, worst_pressure, pressure_tolerance);
  // The comparison can fail: the same record against a 15 mm sine differs by far more.
  std::mt19937_64 rng2(12);
  const rig::MatrixEntry other{"j", "middle", 2.0, 0.133, 0.015};
  const Harmonics c = AlignedHarmonics(direct.RunPeriodic(other, 200.0, kPeriods, rng2, nullptr, nullptr, {}, 0.0), K);
  double worst_other = 0;
  for (int bin = 0; bin < 40; ++bin) {
    const double theta = 2 * std::numbers::pi * (bin + 0.5) / 40;
    worst_other = std::max(worst_other, std::abs(Waveform(a.force, theta) - Waveform(c.force, theta)));
  }
  EXPECT_GT(worst_other, 3 * force_tolerance) << "a 15 mm sine looks like a 10 mm one";
}

TEST(ServedRig, ControllerLostMidRunFailsFastAndTheRecordingEndsAborted) {
  test::TempDir dir;
  const std::string path = dir.file("lost.h5");
  Loopback rig(0.133);
  rig.controller->WriteSetPoint(SetPointJ());
  rig.controller->Arm();
  ASSERT_TRUE(rig.WaitFor([](const auto& s) { return (s.status_word & status_bits::kAtStatic) != 0; }, 10s));
  rig.controller->Run();
  ASSERT_TRUE(rig.WaitFor([](const auto& s) { return s.cycles >= 1; }, 10s));
  daq::RecordingMetadata meta;
  meta.damper_serial = "SIM";
  meta.rig = "served";
  auto recorder = daq::Recorder::Open(path, meta);
  const daq::Experiment header = rig::PeriodicExperimentOf(kJ, 5, rig.server->simulated_sample_rate());
  recorder.BeginExperiment(daq::AcquiredExperiment(header, rig.acquisition->description()));
  std::size_t recorded = 0;
  std::optional<std::int64_t> origin;
  rig.server->StopController();  // mid-run: the controller goes away, the stream goes on
  const auto lost_at = Clock::now();
  std::optional<DeviceError> failure;
  while (!failure && Clock::now() - lost_at < 5s) {
    const daq::AcquiredBlock b = rig.acquisition->Read(20ms);
    if (!b.empty()) {
      daq::SampleBlock block = daq::RecordedBlock(b);
      if (!origin) origin = block.monotonic_ns.front();
      daq::ToRecordedTime(block, *origin, rig.server->options().speed);
      recorder.Append(block);
      recorded += b.size();
    }
    try {
      rig.controller->ReadStatus();
    } catch (const DeviceError& e) {
      failure = e;
    }
  }
  ASSERT_TRUE(failure) << "the controller's loss went unnoticed for 5 s";
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - lost_at).count(), 2.0);
  EXPECT_TRUE(failure->kind() == DeviceError::Kind::kConnection || failure->kind() == DeviceError::Kind::kTimeout)
      << failure->what();
  EXPECT_NE(std::string(failure->what()).find(rig.server->modbus_endpoint().ToString()), std::string::npos);
  recorder.Event(daq::MonotonicNs(), "abort", std::string("controller lost: ") + failure->what());
  recorder.EndExperiment(daq::EndStatus::kAborted);
  recorder.Close();
  const daq::Session s = daq::ReadSession(path);
  EXPECT_EQ(s.experiments.at(0).status, "aborted");
  EXPECT_EQ(s.experiments.at(0).sample_count(), static_cast<long>(recorded));
}

TEST(ServedRig, FrozenStreamGivesStaleBlocksThenAGapWhenItFlowsAgain) {
  Loopback rig(0.05);
  ASSERT_TRUE(rig.WaitFor([](const auto& s) { return s.time_ms > 500; }, 5s));
  rig.server->FreezeStream(true);
  const auto frozen_at = Clock::now();
  bool stale = false;
  while (!stale && Clock::now() - frozen_at < 3s) {
    const daq::AcquiredBlock b = rig.acquisition->Read(20ms);
    stale = b.quality.has(Quality::kStale);
  }
  ASSERT_TRUE(stale) << "no stale block within 3 s of the freeze";
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - frozen_at).count(), 1.0);  // stale_after 250 ms
  rig.server->FreezeStream(false);
  std::optional<daq::AcquiredBlock> resumed;
  const auto thawed_at = Clock::now();
  while (!resumed && Clock::now() - thawed_at < 3s) {
    daq::AcquiredBlock b = rig.acquisition->Read(20ms);
    if (!b.empty()) resumed = std::move(b);
  }
  ASSERT_TRUE(resumed);
  EXPECT_TRUE(resumed->quality.has(Quality::kSequenceGap)) << resumed->quality.ToString();
  EXPECT_GT(resumed->lost_before, 20u);  // the frozen stretch's sample sets, 0.25 s at speed 10 and more
  EXPECT_GT(rig.acquisition->stats().stale_periods, 0u);
}

TEST(ServedRig, StreamsCanFdFramesWithoutLoss) {
  Loopback rig(0.05, 10.0, /*fd=*/true);
  EXPECT_TRUE(rig.acquisition->description().sample_rate > 0);
  ASSERT_FALSE(rig.WaitFor([](const auto&) { return false; }, 500ms));
  std::size_t sets = 0;
  for (const auto& b : rig.blocks) {
    EXPECT_TRUE(b.quality.valid()) << b.quality.ToString();
    sets += b.size();
  }
  EXPECT_GT(sets, 500u);  // 0.5 s at 2000 sets per wall second, less the start
  EXPECT_EQ(rig.acquisition->stats().lost_sample_sets, 0u);
  EXPECT_EQ(rig.acquisition->stats().corrupt_frames, 0u);
}

TEST(ServedRig, ChangingTheSineWhileRunningIsAModbusExceptionWithTheReason) {
  Loopback rig(0.133);
  rig.controller->WriteSetPoint(SetPointJ());
  rig.controller->Arm();
  ASSERT_TRUE(rig.WaitFor([](const auto& s) { return (s.status_word & status_bits::kAtStatic) != 0; }, 10s));
  rig.controller->Run();
  daq::SetPoint bigger = SetPointJ();
  bigger.amplitude = 0.02;
  try {
    rig.controller->WriteSetPoint(bigger);
    FAIL() << "accepted";
  } catch (const DeviceError& e) {
    EXPECT_EQ(e.kind(), DeviceError::Kind::kRefused) << e.what();
    EXPECT_NE(std::string(e.what()).find("cannot change mid-run"), std::string::npos) << e.what();
  }
  const daq::ControllerStatus s = rig.controller->ReadStatus();
  EXPECT_EQ(s.state, ControllerState::kRunning);
  EXPECT_FLOAT_EQ(rig.controller->ReadSetPoint().amplitude, SetPointJ().amplitude);
}

TEST(ServedRig, ForceLimitTripMidSineLatchesTheFaultAndTheRigHolds) {
  Loopback rig(0.133);
  daq::SetPoint sp = SetPointJ();
  rig.controller->WriteSetPoint(sp);
  rig.controller->Arm();
  ASSERT_TRUE(rig.WaitFor([](const auto& s) { return (s.status_word & status_bits::kAtStatic) != 0; }, 10s));
  sp.limits.force_max = rig.controller->ReadStatus().force + 600.0;  // below the sine's peak
  rig.controller->WriteSetPoint(sp);
  rig.controller->Run();
  daq::ControllerStatus tripped;
  ASSERT_TRUE(rig.WaitFor(
      [&](const auto& s) {
        tripped = s;
        return s.faulted();
      },
      10s));
  EXPECT_EQ(tripped.state, ControllerState::kFaulted);
  EXPECT_EQ(tripped.fault_word, fault_bits::kForceLimit);
  EXPECT_EQ(tripped.status_word & status_bits::kHydraulicsOn, 0);
  EXPECT_EQ(daq::FaultBitsText(tripped.fault_word), "force-limit");
  // The rig holds: over the next half second of samples the stroke stays put.
  rig.blocks.clear();
  ASSERT_FALSE(rig.WaitFor([&](const auto&) { return false; }, 500ms));
  double lo = INFINITY, hi = -INFINITY;
  for (const auto& b : rig.blocks)
    for (double y : b.values[0]) lo = std::min(lo, y), hi = std::max(hi, y);
  ASSERT_TRUE(std::isfinite(lo));
  EXPECT_LT(hi - lo, 3e-4) << "the stroke moved after the trip";
  try {
    rig.controller->Run();
    FAIL() << "run accepted with a latched fault";
  } catch (const DeviceError& e) {
    EXPECT_NE(std::string(e.what()).find("fault is latched"), std::string::npos) << e.what();
  }
}

// The simulated rig as a kind of rig (daq/rig_devices.h): "sim" and only "sim" (with its own
// acquisition) is taken, and the drivers it makes read the served rig's stream and status.
TEST(ServedRig, TheSimulatedRigFactoryServesTheRigBehindTheDriversItMakes) {
  const SimulatedRigFactory served(DefaultTruth(), 10.0);
  const daq::NetworkRigFactory network;
  daq::RigConnection c;
  c.controller = "sim";
  EXPECT_TRUE(served.Accepts(c));
  c.acquisition = "sim";
  EXPECT_TRUE(served.Accepts(c));
  c.acquisition = "udp:127.0.0.1:5000";
  EXPECT_FALSE(served.Accepts(c));
  EXPECT_THROW(served.Connect(c), std::invalid_argument);
  c.controller = "127.0.0.1:1502";
  EXPECT_FALSE(served.Accepts(c));
  c = {};
  c.controller = "sim";
  c.response_timeout = 300ms;
  const daq::RigDevices devices = daq::ConnectRig(c, std::vector<const daq::RigDeviceFactory*>{&network, &served});
  const RigServer* server = ServedRig(devices);
  ASSERT_NE(server, nullptr);
  EXPECT_EQ(devices.description.find(DefaultTruth().rig + " [simulated in-process at 10x real time: "), 0u)
      << devices.description;
  EXPECT_EQ(devices.controller->ReadStatus().state, ControllerState::kDisarmed);
  devices.acquisition->Start();
  std::size_t sets = 0;
  for (const auto t0 = Clock::now(); sets < 100 && Clock::now() - t0 < 10s;)
    sets += devices.acquisition->Read(100ms).size();
  EXPECT_GE(sets, 100u);
  EXPECT_DOUBLE_EQ(devices.acquisition->description().sample_rate, 10.0 * server->simulated_sample_rate());
  EXPECT_GT(server->stats().sets_sent, 0u);
  // A rig on the network has no server behind its devices.
  EXPECT_EQ(ServedRig(daq::RigDevices{}), nullptr);
}

}  // namespace
}  // namespace strut::sim
