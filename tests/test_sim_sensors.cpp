// Sensors of the simulated rig: calibration errors, noise, the 16-bit converter with saturation,
// the faults that can be injected (dropout, stuck value, spikes, disconnected channel), and the
// white sensor noise added to a clean session.
#include <gtest/gtest.h>

#include <cmath>
#include <numeric>

#include "strut/sim/periodic_session.h"
#include "strut/sim/sensors.h"

namespace strut::sim {
namespace {

SensorOptions Force() { return {"N", -60e3, 60e3, 20.0, 60.0, 2e-3, 16}; }

TEST(SimSensors, ConverterQuantisesToItsStepAndSaturatesAtTheRangeEnds) {
  const SensorChannel adc(Force());
  const double lsb = 120e3 / 65535.0;
  EXPECT_DOUBLE_EQ(adc.options().lsb(), lsb);
  for (const double v : {-12345.678, 0.0, 3.3, 59999.0}) {
    const double q = adc.Quantise(v);
    EXPECT_LE(std::abs(q - v), 0.5 * lsb + 1e-9);
    EXPECT_NEAR(std::remainder(q + 60e3, lsb), 0.0, 1e-6);  // on the code grid
  }
  EXPECT_DOUBLE_EQ(adc.Quantise(1e6), 60e3);
  EXPECT_DOUBLE_EQ(adc.Quantise(-1e6), -60e3);
  SensorOptions ideal = Force();
  ideal.bits = 0;
  EXPECT_DOUBLE_EQ(SensorChannel(ideal).Quantise(1e6), 1e6);  // no converter
}

TEST(SimSensors, ReadingsCarryGainOffsetAndNoiseOfTheGivenSize) {
  SensorChannel channel(Force());
  std::mt19937_64 rng(7);
  const std::vector<double> physical(20000, 10000.0);
  const auto r = channel.Acquire(physical, 200.0, 0.0, {}, rng);
  const double mean = std::accumulate(r.begin(), r.end(), 0.0) / r.size();
  double var = 0;
  for (double v : r) var += (v - mean) * (v - mean);
  EXPECT_NEAR(mean, 1.002 * 10000.0 + 60.0, 0.5);
  EXPECT_NEAR(std::sqrt(var / r.size()), 20.0, 0.5);
  // Same seed, same readings.
  std::mt19937_64 again(7);
  SensorChannel twin(Force());
  EXPECT_EQ(twin.Acquire(physical, 200.0, 0.0, {}, again), r);
}

TEST(SimSensors, FaultsActOnlyInTheirWindowAndChannel) {
  SensorOptions o = Force();
  o.noise = 0.0;
  std::vector<double> ramp(1000);
  for (std::size_t i = 0; i < ramp.size(); ++i) ramp[i] = 10.0 * i;  // 0..10 kN at 100 Hz over 10 s
  std::mt19937_64 rng(1);
  const auto read = [&](FaultSpec f) {
    SensorChannel c(o);
    const std::vector<FaultSpec> faults{f};
    return c.Acquire(ramp, 100.0, 0.0, faults, rng);
  };
  const auto clean = SensorChannel(o).Acquire(ramp, 100.0, 0.0, {}, rng);

  FaultSpec dropout{"*", "force", FaultKind::kDropout, 2.0, 1.0};
  const auto d = read(dropout);
  for (int i = 0; i < 1000; ++i) {
    if (i >= 200 && i < 300)
      EXPECT_NEAR(d[i], 60.0, o.lsb()) << i;  // the zero error alone
    else
      EXPECT_EQ(d[i], clean[i]) << i;
  }

  FaultSpec stuck{"*", "force", FaultKind::kStuck, 5.0, 0.0};
  const auto s = read(stuck);
  for (int i = 500; i < 1000; ++i) EXPECT_EQ(s[i], clean[500]);
  EXPECT_EQ(s[499], clean[499]);

  FaultSpec disconnected{"*", "force", FaultKind::kDisconnected, 0.0, 0.0};
  for (double v : read(disconnected)) EXPECT_DOUBLE_EQ(v, -60e3);  // the lower rail

  FaultSpec spikes{"*", "force", FaultKind::kSpikes, 0.0, 0.0, 5.0, 0.1};
  const auto k = read(spikes);
  int count = 0;
  for (int i = 0; i < 1000; ++i)
    if (std::abs(k[i] - clean[i]) > 1.0) {
      ++count;
      EXPECT_NEAR(std::abs(k[i] - clean[i]), 12e3, 2 * o.lsb());  // 0.1 of the range
    }
  EXPECT_GT(count, 25);  // about 5 per second for 10 s
  EXPECT_LT(count, 80);

  // A fault that begins in one block holds its stuck value in the next.
  SensorChannel c(o);
  const std::vector<FaultSpec> faults{FaultSpec{"*", "force", FaultKind::kStuck, 0.5, 0.0}};
  const std::vector<double> first(ramp.begin(), ramp.begin() + 100), second(ramp.begin() + 100, ramp.begin() + 200);
  const auto a = c.Acquire(first, 100.0, 0.0, faults, rng);
  const auto b = c.Acquire(second, 100.0, 1.0, faults, rng);
  EXPECT_EQ(a[99], a[50]);
  for (double v : b) EXPECT_EQ(v, a[50]);

  EXPECT_TRUE(dropout.Applies("c", "force"));
  EXPECT_FALSE(dropout.Applies("c", "pressure"));
  FaultSpec only_c = dropout;
  only_c.experiment = "c";
  EXPECT_FALSE(only_c.Applies("d", "force"));
}

TEST(SimSensors, InvalidSettingsAreRejectedWithTheReason) {
  std::string error;
  SensorOptions o = Force();
  o.range_min = 1.0, o.range_max = 0.0;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_NE(error.find("range"), std::string::npos);
  o = Force();
  o.bits = 4;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_THROW(SensorChannel{o}, std::invalid_argument);
  FaultSpec f{"*", "humidity", FaultKind::kDropout, 0.0, 0.0};
  EXPECT_FALSE(f.IsValid(&error));
  EXPECT_THROW(ParseFaultKind("gremlins"), std::invalid_argument);
  EXPECT_EQ(ParseFaultKind("stuck"), FaultKind::kStuck);
}

TEST(SimSensorNoise, AddsEachChannelsNoiseAndLeavesTheOthers) {
  daq::Experiment e;
  for (const char* name : {"stroke", "force", "pressure", "temperature"})
    e.channels.push_back({name, "", "", std::vector<double>(20000, 1.0)});
  daq::Session session;
  session.experiments = {e, e};
  SensorNoise noise;
  noise.force = 0.0;  // a channel without noise keeps its samples
  std::mt19937_64 rng(7);
  AddSensorNoise(session, noise, rng);
  for (const daq::Experiment& x : session.experiments) {
    const auto sd = [&](const char* name) {
      const std::vector<double>& v = x.channel(name).samples;
      double ss = 0.0;
      for (double s : v) ss += (s - 1.0) * (s - 1.0);
      return std::sqrt(ss / v.size());
    };
    EXPECT_NEAR(sd("stroke") / noise.stroke, 1.0, 0.03);  // 20000 samples: the estimate within 0.5 % (1 sd)
    EXPECT_NEAR(sd("pressure") / noise.pressure, 1.0, 0.03);
    EXPECT_EQ(sd("force"), 0.0);
    EXPECT_EQ(sd("temperature"), 0.0);
  }
  // Every sample its own draw: the two experiments' noise differs.
  EXPECT_NE(session.experiments[0].channel("stroke").samples[0], session.experiments[1].channel("stroke").samples[0]);
}

}  // namespace
}  // namespace strut::sim
