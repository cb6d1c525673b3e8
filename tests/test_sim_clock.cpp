// The simulation clock: as fast as possible, or paced to the wall clock at a chosen speed.
#include <gtest/gtest.h>

#include <chrono>

#include "strut/sim/clock.h"

namespace strut::sim {
namespace {

using namespace std::chrono_literals;

// A fake wall clock that advances only when the clock sleeps (or when the test says so).
struct FakeTime {
  SimulationClock::TimePoint now{};
  std::vector<double> sleeps;  // s slept, in order
  SimulationClock Make(ClockOptions o) {
    return SimulationClock(
        o, [this] { return now; },
        [this](SimulationClock::TimePoint until) {
          sleeps.push_back(std::chrono::duration<double>(until - now).count());
          now = until;
        });
  }
};

TEST(SimClock, FastModeNeverWaits) {
  FakeTime time;
  SimulationClock clock = time.Make({ClockMode::kFast, 1.0});
  clock.Start();
  EXPECT_EQ(clock.WaitUntil(100.0), 0.0);
  EXPECT_TRUE(time.sleeps.empty());
}

TEST(SimClock, RealTimeModeReleasesSamplesWhenTheyAreDue) {
  FakeTime time;
  SimulationClock clock = time.Make({ClockMode::kRealTime, 2.0});  // twice as fast as real time
  clock.Start();
  clock.WaitUntil(1.0);
  ASSERT_EQ(time.sleeps.size(), 1u);
  EXPECT_NEAR(time.sleeps[0], 0.5, 1e-9);
  time.now += 2s;  // the computation falls behind
  EXPECT_NEAR(clock.WaitUntil(3.0), 1.0, 1e-9);  // due at 1.5 s, it is 2.5 s
  EXPECT_EQ(time.sleeps.size(), 1u);
  EXPECT_NEAR(clock.max_lateness(), 1.0, 1e-9);
  EXPECT_NEAR(clock.Elapsed(), 2.5, 1e-9);
}

TEST(SimClock, RealTimeModeTracksTheWallClock) {
  SimulationClock clock({ClockMode::kRealTime, 10.0});
  clock.Start();
  clock.WaitUntil(0.5);  // 50 ms of wall time
  EXPECT_GE(clock.Elapsed(), 0.049);
  EXPECT_LT(clock.Elapsed(), 1.0);
}

TEST(SimClock, SpeedMustBePositive) {
  EXPECT_THROW(SimulationClock({ClockMode::kRealTime, 0.0}), std::invalid_argument);
  std::string error;
  EXPECT_FALSE((ClockOptions{ClockMode::kRealTime, -1.0}).IsValid(&error));
  EXPECT_NE(error.find("speed"), std::string::npos);
}

}  // namespace
}  // namespace strut::sim
