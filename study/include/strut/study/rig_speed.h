// The standard matrix through the real drivers on the simulated rig at several clock speeds, side
// by side with `strut sim matrix` on the same truth (`strut bench rig`, docs/rig-run.md
// "Benchmark"): wall and CPU time per simulated second, and the fastest speed that keeps up. The
// runs through the drivers are the caller's (the CLI wires the served rig to them).
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "strut/daq/session.h"
#include "strut/sim/simulated_rig.h"

namespace strut::study {

//! One run of the matrix through the drivers.
struct RigRunFigures {
  double wall = 0.0, cpu = 0.0, plant_cpu = 0.0;  //!< s; cpu: the whole process (plant, servers, runner, recorder)
  double simulated = 0.0;                         //!< the served rig's clock, s (moves, settling, records)
  double recorded = 0.0;                          //!< s of samples in the session
  std::size_t complete = 0, not_steady = 0, aborted = 0;
  bool finished = false;  //!< the run ended complete
  std::uint64_t lost_sets = 0, gaps = 0;
  //! Frames the receiver refused: ahead of its clock, late (behind the stream) or corrupt.
  std::uint64_t refused_frames = 0;
  double max_lateness = 0.0;  //!< s the stream was ever behind its schedule
  //! Every experiment complete and steady, nothing lost, and the stream never half a second behind
  //! its schedule (a run that completes slower than asked did not keep up).
  bool kept_up(std::size_t experiments) const {
    return finished && complete == experiments && not_steady == 0 && aborted == 0 && lost_sets == 0 && gaps == 0 &&
           max_lateness <= 0.5;
  }
};

//! Seconds the session's experiments hold (samples / rate).
double RecordedSeconds(const daq::Session& session);

//! `strut sim matrix` on the truth: the library call the command makes and its write to `path`
//! (removed again), medians of `repeats`.
struct SimMatrixTiming {
  double wall = 0.0, cpu = 0.0;  //!< s; cpu: the whole process
  double simulated = 0.0, recorded = 0.0;  //!< s of the rig's clock and of samples (the same every time: one seed)
};
SimMatrixTiming TimeSimMatrix(const sim::Truth& truth, const rig::MatrixPlan& plan, unsigned long seed, int repeats,
                              const std::string& path);

//! One speed's runs and their medians.
struct RigSpeedRow {
  double speed = 0.0;
  std::vector<RigRunFigures> runs;
  double wall = 0.0, cpu = 0.0, plant = 0.0, simulated = 0.0, recorded = 0.0, behind = 0.0;  //!< medians
  double per_wall = 0.0, per_cpu = 0.0;  //!< medians of simulated s per wall and per CPU s
  std::size_t complete = 0;              //!< the worst run's complete experiments
  std::uint64_t lost = 0, gaps = 0, refused = 0;  //!< the worst run's
  std::size_t kept = 0;                  //!< runs that kept up
  bool kept_up() const { return kept == runs.size(); }
};
RigSpeedRow SummariseSpeed(double speed, std::vector<RigRunFigures> runs, std::size_t experiments);

//! The fastest speed whose runs all kept up; none when none did.
std::optional<double> FastestKeptUp(const std::vector<RigSpeedRow>& rows);

}  // namespace strut::study
