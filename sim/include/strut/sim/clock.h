// The simulation clock: simulated time either runs as fast as the computer allows (tests, demo,
// batch datasets) or is paced to the wall clock (end-to-end runs over the real drivers, where a
// consumer expects samples when a real rig would deliver them).
#pragma once

#include <chrono>
#include <functional>
#include <string>

namespace strut::sim {

enum class ClockMode {
  kFast,      //!< no waiting: simulated time runs as fast as it is computed
  kRealTime,  //!< WaitUntil(t) returns when the wall clock reaches start + t / speed
};

struct ClockOptions {
  ClockMode mode = ClockMode::kFast;
  //! Simulated seconds per wall second when paced (1 = real time, 2 = twice as fast).
  double speed = 1.0;
  bool IsValid(std::string* error) const;
};

//! Paces simulated time. The time source and the sleep are injectable for tests.
class SimulationClock {
 public:
  using TimePoint = std::chrono::steady_clock::time_point;
  using Now = std::function<TimePoint()>;
  using SleepUntil = std::function<void(TimePoint)>;

  //! Throws std::invalid_argument on invalid options. Empty functions mean std::chrono::steady_clock
  //! and std::this_thread::sleep_until.
  explicit SimulationClock(ClockOptions options = {}, Now now = {}, SleepUntil sleep = {});

  const ClockOptions& options() const { return options_; }
  //! Starts (or restarts) the clock: simulated time 0 is now.
  void Start();
  //! Fast: returns at once. Real time: sleeps until the wall clock reaches simulated time t.
  //! Returns how late the simulation was at t (s of wall time, >= 0): the computation did not
  //! keep up when this grows.
  double WaitUntil(double simulated_seconds);
  //! Wall seconds since Start().
  double Elapsed() const;
  //! Largest lateness WaitUntil has seen, s.
  double max_lateness() const { return max_lateness_; }

 private:
  ClockOptions options_;
  Now now_;
  SleepUntil sleep_;
  TimePoint start_{};
  bool started_ = false;
  double max_lateness_ = 0.0;
};

}  // namespace strut::sim
