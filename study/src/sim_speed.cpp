#include "strut/study/sim_speed.h"

#include <chrono>

namespace strut::study {

SimSpeedStudy MeasureSimSpeed(const sim::Truth& truth) {
  using Clock = std::chrono::steady_clock;
  const sim::SimulatedRig rig(truth);
  SimSpeedStudy study;
  study.composition = rig.model().composition();
  const auto start = Clock::now();
  rig.RunMatrix(rig::StandardMatrixPlan(), {}, &study.experiments);
  study.matrix_wall = std::chrono::duration<double>(Clock::now() - start).count();
  for (const sim::PeriodicRunReport& r : study.experiments) study.simulated += r.simulated_seconds;
  const auto drop_start = Clock::now();
  rig.RunDropSession(study.drop, {}, &study.drop_report);
  study.drop_wall = std::chrono::duration<double>(Clock::now() - drop_start).count();
  return study;
}

}  // namespace strut::study
