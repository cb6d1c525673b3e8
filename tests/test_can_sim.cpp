// The simulated rig as an acquisition module on CAN: an experiment of sim::SimulatedRig streams
// through sim::CanModule over UDP on loopback into daq::CanAcquisition, and what arrives is what
// the rig recorded directly, to within half an ADC count.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <thread>

#include "strut/daq/can_acquisition.h"
#include "strut/sim/can_module.h"
#include "strut/sim/simulated_rig.h"

namespace strut::sim {
namespace {

using namespace std::chrono_literals;

TEST(SimCanModule, ExperimentArrivesOverCanAsTheRigRecordedIt) {
  const Truth truth = DefaultTruth();
  const SimulatedRig rig(truth);
  const double rate = truth.acquisition.sample_rate;
  auto receiver = daq::UdpCanTransport::Listen("127.0.0.1", 0);
  const std::uint16_t port = receiver->local_port();
  CanModule module(daq::UdpCanTransport::Connect("127.0.0.1", port), truth.sensors, rate);
  daq::CanAcquisition acquisition(std::move(receiver), module.ReceiverOptions());
  acquisition.Start();

  // The reader runs beside the fast simulation, as a recording client would.
  std::vector<double> stroke, force, pressure;
  std::atomic<bool> done{false};
  std::thread reader([&] {
    for (int empty = 0; !done || empty < 2;) {
      const daq::AcquiredBlock b = acquisition.Read(50ms);
      if (b.empty()) {
        empty += done ? 1 : 0;
        continue;
      }
      EXPECT_TRUE(b.quality.valid()) << b.quality.ToString();
      stroke.insert(stroke.end(), b.values[0].begin(), b.values[0].end());
      force.insert(force.end(), b.values[1].begin(), b.values[1].end());
      pressure.insert(pressure.end(), b.values[2].begin(), b.values[2].end());
    }
  });
  std::vector<double> sent_stroke, sent_force, sent_pressure;
  const SampleSink sink = [&](const SampleBlock& block) {
    sent_stroke.insert(sent_stroke.end(), block.stroke.begin(), block.stroke.end());
    sent_force.insert(sent_force.end(), block.force.begin(), block.force.end());
    sent_pressure.insert(sent_pressure.end(), block.pressure.begin(), block.pressure.end());
    module.Send(block);
  };
  std::mt19937_64 rng(5);
  const rig::MatrixEntry n{"n", "low", 2.0, 0.014, 0.010};
  const daq::Experiment e = rig.RunPeriodic(n, rate, 3, rng, nullptr, nullptr, sink);
  done = true;
  reader.join();

  ASSERT_EQ(stroke.size(), sent_stroke.size());
  EXPECT_EQ(module.sets_sent(), sent_stroke.size());
  EXPECT_EQ(acquisition.stats().lost_sample_sets, 0u);
  EXPECT_EQ(acquisition.stats().corrupt_frames, 0u);
  const auto half_count = [](const SensorOptions& s) { return 0.5 * s.lsb() + 1e-9 * (s.range_max - s.range_min); };
  for (std::size_t i = 0; i < stroke.size(); ++i) {
    ASSERT_NEAR(stroke[i], sent_stroke[i], half_count(truth.sensors.stroke)) << i;
    ASSERT_NEAR(force[i], sent_force[i], half_count(truth.sensors.force)) << i;
    ASSERT_NEAR(pressure[i], sent_pressure[i], half_count(truth.sensors.pressure)) << i;
  }
  // The recorded periods are the end of the stream.
  const auto& recorded = e.channel("force").samples;
  ASSERT_LE(recorded.size(), force.size());
  const std::size_t offset = force.size() - recorded.size();
  for (std::size_t i = 0; i < recorded.size(); ++i)
    ASSERT_NEAR(force[offset + i], recorded[i], half_count(truth.sensors.force)) << i;
}

TEST(SimCanModule, RefusesABlockAtAnotherRateAndNonSixteenBitSensors) {
  const Truth truth = DefaultTruth();
  CanModule module(daq::UdpCanTransport::Connect("127.0.0.1", 9), truth.sensors, 200.0);
  SampleBlock drop;
  drop.experiment = "drop";
  drop.sample_rate = 1000.0;
  drop.stroke = drop.force = drop.pressure = {0.0};
  try {
    module.Send(drop);
    FAIL() << "accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("experiment drop"), std::string::npos) << e.what();
  }
  SensorSet twelve = truth.sensors;
  twelve.force.bits = 12;
  EXPECT_THROW(CanChannels(twelve), std::invalid_argument);
}

}  // namespace
}  // namespace strut::sim
