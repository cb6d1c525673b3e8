#include "strut/sim/clock.h"

#include <cmath>
#include <fmt/format.h>
#include <stdexcept>
#include <thread>

namespace strut::sim {

bool ClockOptions::IsValid(std::string* error) const {
  if (!std::isfinite(speed) || !(speed > 0)) {
    if (error) *error = fmt::format("clock speed must be positive, got {}", speed);
    return false;
  }
  return true;
}

SimulationClock::SimulationClock(ClockOptions options, Now now, SleepUntil sleep)
    : options_(options), now_(std::move(now)), sleep_(std::move(sleep)) {
  std::string error;
  if (!options_.IsValid(&error)) throw std::invalid_argument("simulation clock: " + error);
  if (!now_) now_ = [] { return std::chrono::steady_clock::now(); };
  if (!sleep_) sleep_ = [](TimePoint t) { std::this_thread::sleep_until(t); };
}

void SimulationClock::Start() {
  start_ = now_();
  started_ = true;
  max_lateness_ = 0.0;
}

double SimulationClock::Elapsed() const {
  if (!started_) return 0.0;
  return std::chrono::duration<double>(now_() - start_).count();
}

double SimulationClock::WaitUntil(double simulated_seconds) {
  if (!started_) Start();
  if (options_.mode == ClockMode::kFast) return 0.0;
  const auto due = start_ + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                std::chrono::duration<double>(simulated_seconds / options_.speed));
  const auto now = now_();
  if (now >= due) {
    const double late = std::chrono::duration<double>(now - due).count();
    max_lateness_ = std::max(max_lateness_, late);
    return late;
  }
  sleep_(due);
  return 0.0;
}

}  // namespace strut::sim
