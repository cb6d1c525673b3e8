// The simulated servo controller with its plant (sim::SimulatedController), driven directly: the
// command program against finite differences, the state machine's rules and timing, the stroke
// following the command, the interlocks holding the piston, and determinism. Over the real
// protocols: test_sim_served_rig.cpp.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "strut/sim/actuator.h"
#include "strut/sim/simulated_controller.h"

namespace strut::sim {
namespace {

using daq::ControllerCommand;
using daq::ControllerState;
namespace status_bits = daq::status_bits;
namespace fault_bits = daq::fault_bits;

TEST(CommandProgram, SineRampsInAndOutOverWholeCyclesWithConsistentRates) {
  CommandProgram p = CommandProgram::Sine(1.0, 0.133, 0.01, 2.0, 2);
  EXPECT_DOUBLE_EQ(p.At(1.0).value, 0.133);  // starts at the mean
  EXPECT_DOUBLE_EQ(p.Envelope(1.5), 0.5);    // one of two ramp cycles
  EXPECT_DOUBLE_EQ(p.Envelope(2.0), 1.0);
  EXPECT_EQ(p.Cycles(2.99), 3u);
  p.stop_at = p.NextCycleBoundary(3.1);
  EXPECT_DOUBLE_EQ(p.stop_at, 3.5);
  EXPECT_DOUBLE_EQ(p.End(), 4.5);
  EXPECT_NEAR(p.Envelope(4.0), 0.5, 1e-12);
  EXPECT_NEAR(p.At(4.5).value, 0.133, 1e-15);
  EXPECT_EQ(p.Cycles(10.0), 7u);  // counting stops with the ramp out
  // Rates against central differences, away from the envelope's corners.
  for (double t : {1.13, 1.71, 2.37, 3.21, 3.77, 4.12}) {
    const double h = 1e-6;
    const InputSample a = p.At(t);
    EXPECT_NEAR(a.rate, (p.At(t + h).value - p.At(t - h).value) / (2 * h), 1e-6) << t;
    EXPECT_NEAR(a.accel, (p.At(t + h).rate - p.At(t - h).rate) / (2 * h), 1e-3) << t;
  }
  // Amplitude 0 at frequency 0 (a valid set-point) holds the mean and stops at once.
  CommandProgram hold = CommandProgram::Sine(0.0, 0.1, 0.0, 0.0, 2);
  EXPECT_DOUBLE_EQ(hold.At(3.0).value, 0.1);
  hold.stop_at = hold.NextCycleBoundary(3.0);
  EXPECT_DOUBLE_EQ(hold.End(), 3.0);
  const CommandProgram move = CommandProgram::Move(0.0, 0.01, 0.05, 0.02);
  EXPECT_DOUBLE_EQ(move.End(), 2.0);
  EXPECT_DOUBLE_EQ(move.At(1.0).value, 0.03);
  EXPECT_DOUBLE_EQ(move.At(1.0).rate, 0.02);
  EXPECT_DOUBLE_EQ(move.At(3.0).value, 0.05);
}

TEST(ChebyshevSignal, DerivativesAreThoseOfTheFunction) {
  const auto f = [](double t) { return 0.1 * std::sin(2 * std::numbers::pi * 2.0 * t) + 0.02 * t * t; };
  const ChebyshevSignal s = ChebyshevSignal::Fit(f, 3.0, 3.05, 16);
  const double w = 2 * std::numbers::pi * 2.0;
  for (double t : {3.0, 3.013, 3.031, 3.05}) {
    const InputSample v = s.At(t);
    EXPECT_NEAR(v.value, f(t), 1e-14);
    EXPECT_NEAR(v.rate, 0.1 * w * std::cos(w * t) + 0.04 * t, 1e-10);
    EXPECT_NEAR(v.accel, -0.1 * w * w * std::sin(w * t) + 0.04, 1e-6);
  }
  EXPECT_THROW(ChebyshevSignal::Fit(f, 1.0, 1.0, 8), std::invalid_argument);
}

daq::SetPoint SetPointJ() {
  daq::SetPoint sp;
  sp.static_position = 0.133;
  sp.amplitude = 0.010;
  sp.frequency = 2.0;
  sp.ramp_cycles = 2;
  sp.static_rate = 0.02;
  return sp;
}

struct Stream {
  std::vector<double> time, stroke, force;
  SampleSink sink() {
    return [this](const SampleBlock& b) {
      for (std::size_t i = 0; i < b.stroke.size(); ++i) time.push_back(b.start_time + i / b.sample_rate);
      stroke.insert(stroke.end(), b.stroke.begin(), b.stroke.end());
      force.insert(force.end(), b.force.begin(), b.force.end());
    };
  }
};

TEST(SimulatedController, RefusesWhatTheStateDoesNotAllowWithAReason) {
  SimulatedController c(DefaultTruth());
  EXPECT_NE(c.Execute(ControllerCommand::kArm).value_or("").find("no set-point"), std::string::npos);
  EXPECT_NE(c.Execute(ControllerCommand::kRun).value_or("").find("not armed"), std::string::npos);
  daq::SetPoint force = SetPointJ();
  force.mode = daq::ControlMode::kForce;
  EXPECT_NE(c.Apply(force).value_or("").find("force control is not simulated"), std::string::npos);
  SimulatedControllerOptions o;
  o.initial_stroke = 0.10;
  SimulatedController d(DefaultTruth(), o);
  ASSERT_FALSE(d.Apply(SetPointJ()));
  ASSERT_FALSE(d.Execute(ControllerCommand::kArm));
  // 33 mm to go at 20 mm/s: run waits for the static position.
  EXPECT_NE(d.Execute(ControllerCommand::kRun).value_or("").find("still moving"), std::string::npos);
  d.Advance(2.0);
  ASSERT_FALSE(d.Execute(ControllerCommand::kRun));
  daq::SetPoint bigger = SetPointJ();
  bigger.amplitude = 0.02;
  EXPECT_NE(d.Apply(bigger).value_or("").find("cannot change mid-run"), std::string::npos);
  daq::SetPoint limits = SetPointJ();
  limits.limits.force_max = 4.0e4;
  EXPECT_FALSE(d.Apply(limits));  // limits alone may change while running
}

TEST(SimulatedController, ArmsRunsAndStopsAsAServoControllerDoes) {
  SimulatedControllerOptions o;
  o.initial_stroke = 0.113;
  SimulatedController c(DefaultTruth(), o);
  Stream s;
  c.Advance(0.5, s.sink());
  EXPECT_EQ(c.Status().state, ControllerState::kDisarmed);
  EXPECT_EQ(c.Status().status_word, 0);
  ASSERT_FALSE(c.Apply(SetPointJ()));
  ASSERT_FALSE(c.Execute(ControllerCommand::kArm));
  const double armed_at = c.time();
  c.Advance(armed_at + 0.5, s.sink());
  daq::ControllerStatus st = c.Status();
  EXPECT_EQ(st.state, ControllerState::kArmed);
  EXPECT_EQ(st.status_word, status_bits::kHydraulicsOn | status_bits::kRamping);
  EXPECT_NEAR(st.command, 0.113 + 0.02 * 0.5, 1e-9);  // 20 mm at 20 mm/s: half-way
  c.Advance(armed_at + 1.5, s.sink());
  st = c.Status();
  EXPECT_EQ(st.status_word, status_bits::kHydraulicsOn | status_bits::kAtStatic);
  EXPECT_NEAR(st.stroke, 0.133, 2e-4);  // LVDT reading: noise 0.03 mm, gain error 0.1 %
  ASSERT_FALSE(c.Execute(ControllerCommand::kRun));
  const double run_at = c.time();
  c.Advance(run_at + 0.6, s.sink());
  EXPECT_EQ(c.Status().status_word, status_bits::kHydraulicsOn | status_bits::kRamping);
  EXPECT_EQ(c.Status().cycles, 1u);
  c.Advance(run_at + 3.0, s.sink());
  st = c.Status();
  EXPECT_EQ(st.state, ControllerState::kRunning);
  EXPECT_EQ(st.status_word, status_bits::kHydraulicsOn | status_bits::kFullAmplitude);
  EXPECT_EQ(st.cycles, 6u);
  // At full amplitude the stroke follows the sine: its fundamental over two cycles.
  double sc = 0, ss = 0;
  std::size_t count = 0;
  for (std::size_t i = 0; i < s.time.size(); ++i) {
    const double t = s.time[i] - run_at;
    if (t < 2.0 || t >= 3.0) continue;
    const double w = 2 * std::numbers::pi * 2.0 * t;
    sc += s.stroke[i] * std::cos(w), ss += s.stroke[i] * std::sin(w), ++count;
  }
  const double amplitude = 2 * std::hypot(sc, ss) / count, lag = std::atan2(-2 * sc / count, 2 * ss / count);
  EXPECT_NEAR(amplitude, 0.010 * 1.001, 2e-5);  // LVDT gain error 0.1 %
  EXPECT_NEAR(lag * 180 / std::numbers::pi, 0.0, 2.0);  // the servo lags by about a degree at 2 Hz
  // Stop: the ramp out starts at the end of the present cycle and takes two cycles.
  ASSERT_FALSE(c.Execute(ControllerCommand::kStop));
  const double stop_at = c.program().stop_at;
  EXPECT_NEAR(std::fmod(stop_at - run_at, 0.5), 0.0, 1e-9);
  EXPECT_EQ(c.Status().state, ControllerState::kStopping);
  c.Advance(stop_at + 0.9, s.sink());
  EXPECT_EQ(c.Status().state, ControllerState::kStopping);
  c.Advance(stop_at + 1.2, s.sink());
  st = c.Status();
  EXPECT_EQ(st.state, ControllerState::kArmed);
  EXPECT_EQ(st.status_word, status_bits::kHydraulicsOn | status_bits::kAtStatic);
  EXPECT_EQ(st.cycles, static_cast<std::uint32_t>(std::lround((stop_at - run_at) * 2.0)) + 2);
  ASSERT_FALSE(c.Execute(ControllerCommand::kDisarm));
  EXPECT_EQ(c.Status().status_word, 0);
}

TEST(SimulatedController, ForceLimitTripsMidSineLatchesAndHoldsThePiston) {
  SimulatedControllerOptions o;
  o.initial_stroke = 0.133;
  SimulatedController c(DefaultTruth(), o);
  Stream s;
  daq::SetPoint sp = SetPointJ();
  ASSERT_FALSE(c.Apply(sp));
  ASSERT_FALSE(c.Execute(ControllerCommand::kArm));
  c.Advance(0.5, s.sink());
  const double static_force = c.Status().force;
  sp.limits.force_max = static_force + 600.0;  // the sine's force swings about +-760 N, plus friction
  ASSERT_FALSE(c.Apply(sp));
  ASSERT_FALSE(c.Execute(ControllerCommand::kRun));
  const double run_at = c.time();
  c.Advance(run_at + 3.0, s.sink());
  const daq::ControllerStatus st = c.Status();
  EXPECT_EQ(st.state, ControllerState::kFaulted);
  EXPECT_EQ(st.fault_word, fault_bits::kForceLimit);
  EXPECT_EQ(st.status_word, 0);  // hydraulics off
  EXPECT_EQ(c.stats().recomputed_chunks, 1);
  // The trip is the first sample beyond the limit; from there the piston holds where it stops.
  std::size_t trip = 0;
  while (trip < s.force.size() && !(s.time[trip] >= run_at && s.force[trip] > sp.limits.force_max)) ++trip;
  ASSERT_LT(trip, s.force.size());
  EXPECT_GT(s.time[trip] - run_at, 0.25);  // mid ramp-in, not at the start
  EXPECT_LT(s.time[trip] - run_at, 1.5);
  for (std::size_t i = trip + 20; i < s.stroke.size(); ++i)
    ASSERT_NEAR(s.stroke[i], s.stroke[trip + 20], 2.5e-4) << "t = " << s.time[i];  // noise 0.03 mm
  EXPECT_NE(c.Execute(ControllerCommand::kArm).value_or("").find("force-limit"), std::string::npos);
  ASSERT_FALSE(c.Execute(ControllerCommand::kResetFaults));
  EXPECT_EQ(c.Status().state, ControllerState::kDisarmed);
  EXPECT_EQ(c.Status().fault_word, 0);
}

TEST(SimulatedController, FollowingErrorTripsWhenTheLoopCannotKeepUp) {
  SimulatedControllerOptions o;
  o.initial_stroke = 0.05;
  o.following_error_limit = 1e-4;  // 0.1 mm: a 0.2 m/s move lags more than that
  SimulatedController c(DefaultTruth(), o);
  daq::SetPoint sp = SetPointJ();
  sp.static_rate = 0.2;
  ASSERT_FALSE(c.Apply(sp));
  ASSERT_FALSE(c.Execute(ControllerCommand::kArm));
  c.Advance(1.0);
  EXPECT_EQ(c.Status().fault_word, fault_bits::kFollowingError);
  EXPECT_EQ(c.Status().state, ControllerState::kFaulted);
}

TEST(SimulatedController, TheSameSeedAndCommandsGiveTheSameSamples) {
  const auto run = [](unsigned long seed) {
    SimulatedControllerOptions o;
    o.initial_stroke = 0.13;
    o.seed = seed;
    SimulatedController c(DefaultTruth(), o);
    Stream s;
    EXPECT_FALSE(c.Apply(SetPointJ()));
    EXPECT_FALSE(c.Execute(ControllerCommand::kArm));
    c.Advance(0.5, s.sink());
    EXPECT_FALSE(c.Execute(ControllerCommand::kRun));
    c.Advance(1.5, s.sink());
    return s.force;
  };
  const std::vector<double> a = run(7), b = run(7), other = run(8);
  ASSERT_EQ(a.size(), 300u);
  EXPECT_EQ(a, b);
  EXPECT_NE(a, other);
}

}  // namespace
}  // namespace strut::sim
