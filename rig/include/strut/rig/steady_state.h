// Steady-state detection of a sine test (docs/rig-run.md, "Steady state"): samples are cut into
// whole cycles of the excitation, each cycle is summarised (peak and trough of stroke and force,
// mean pressure), and the response is steady when consecutive cycles agree within tolerances.
// Standalone: the runner feeds it live samples, replay feeds it a recorded experiment or the
// summaries the runner stored in the session, and both get the same verdict.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <limits>
#include <vector>

#include "strut/daq/session.h"

namespace strut::rig {

//! One whole cycle of the response. Times are monotonic ns of its first and last sample.
struct CycleSummary {
  long cycle = 0;  //!< index since the summariser started
  std::int64_t start_ns = 0, end_ns = 0;
  double stroke_min = 0.0, stroke_max = 0.0;  //!< m
  double force_min = 0.0, force_max = 0.0;    //!< N
  double pressure_mean = 0.0;                 //!< Pa as acquired; NaN without a pressure channel
  double stroke_amplitude() const { return 0.5 * (stroke_max - stroke_min); }
  double force_range() const { return force_max - force_min; }
};

//! Tolerances of the cycle-to-cycle change (defaults in docs/rig-run.md).
struct SteadyStateTolerances {
  //! Largest change of force peak or trough between consecutive cycles, relative to the force range.
  double force = 0.01;
  //! Largest change of stroke peak or trough, relative to the stroke range (twice the amplitude).
  double stroke = 0.005;
  //! Change of the mean pressure, relative to |mean| (at least pressure_floor).
  double pressure = 0.005;
  double pressure_floor = 1.0e5;  //!< Pa: a mean nearer zero is compared with this
  //! Steady after this many consecutive changes within tolerance (so consecutive + 1 cycles agree).
  int consecutive = 2;
  //! The slow thermal drift: the mean pressure may change by at most `pressure_drift` of
  //! max(|mean|, pressure_floor) between the last cycle and the last one that ended `drift_window`
  //! seconds (recorded clock) or more before it; no verdict of steady before that much time. The
  //! gas settles with theta15 / (theta16 (1 + theta6 q)), 8 s at mid stroke and 40 s near full
  //! compression on the shipped damper: a fast cycle's change is far within `pressure` long before
  //! the mean pressure stops drifting at the identification's noise level (a few 1e-4 of it).
  double pressure_drift = 2.0e-4;
  double drift_window = 30.0;
  //! Give up after this many cycles or this much time (s) since the first cycle, whichever first:
  //! the experiment is then recorded all the same and marked not steady.
  int max_cycles = 1500;  // 600 s of a 2 Hz test: the time limit decides
  double time_limit = 600.0;
  //! False with a message naming the item when out of range.
  bool IsValid(std::string* error) const;
};

//! The change between two consecutive cycles, each as a fraction of its tolerance's reference.
struct CycleChange {
  double stroke = 0.0, force = 0.0, pressure = 0.0;
  //! The largest change as a multiple of its tolerance (< 1: within tolerance).
  double worst_ratio(const SteadyStateTolerances& t) const;
};
CycleChange ChangeBetween(const CycleSummary& previous, const CycleSummary& next, const SteadyStateTolerances& t);

struct SteadyStateVerdict {
  bool steady = false;
  bool timed_out = false;   //!< the limit passed before the response settled
  long cycles = 0;          //!< cycles seen
  long steady_at = -1;      //!< the cycle after which it was steady (-1: not yet)
  //! The last change as a multiple of the tolerance (the "steady-state measure"; inf before two cycles).
  double measure = 0.0;
  int agreeing = 0;  //!< consecutive changes within tolerance so far
  CycleChange last_change;  //!< the last change between consecutive cycles (zeros before two cycles)
  //! The mean pressure's change over the drift window, as a fraction of max(|mean|, floor);
  //! NaN before the window has passed (or without pressure, or with the window off).
  double drift = std::numeric_limits<double>::quiet_NaN();
  double elapsed = 0.0;  //!< recorded s since the first cycle began
  bool done() const { return steady || timed_out; }
};

//! Decides steady state from cycle summaries, one at a time.
class SteadyStateDetector {
 public:
  //! Throws std::invalid_argument when the tolerances are not valid.
  explicit SteadyStateDetector(SteadyStateTolerances tolerances = {});
  //! Adds the next cycle; the verdict is final once done() (later cycles do not change it).
  const SteadyStateVerdict& Add(const CycleSummary& cycle);
  const SteadyStateVerdict& verdict() const { return verdict_; }
  const std::vector<CycleSummary>& cycles() const { return cycles_; }
  const SteadyStateTolerances& tolerances() const { return tolerances_; }

 private:
  //! The mean pressure still drifts over the drift window (or the window has not passed).
  bool Drifting() const;
  //! SteadyStateVerdict::drift of the cycles so far.
  double Drift() const;
  SteadyStateTolerances tolerances_;
  std::vector<CycleSummary> cycles_;
  SteadyStateVerdict verdict_;
};

//! The verdict over a list of cycles (e.g. read back from a session).
SteadyStateVerdict DetectSteadyState(std::span<const CycleSummary> cycles, const SteadyStateTolerances& tolerances);

//! Cuts a stream of samples into whole cycles of samples_per_cycle samples from the first one.
class CycleSummariser {
 public:
  //! Throws std::invalid_argument unless samples_per_cycle >= 2.
  explicit CycleSummariser(long samples_per_cycle);
  //! Adds samples (equal lengths; `pressure` may be empty) and returns the cycles they completed.
  std::vector<CycleSummary> Add(std::span<const std::int64_t> time_ns, std::span<const double> stroke,
                                std::span<const double> force, std::span<const double> pressure);
  //! Drops a partly filled cycle (after a gap); cycle numbers go on.
  void Restart();
  long samples_per_cycle() const { return samples_per_cycle_; }
  long cycles() const { return next_cycle_; }
  //! Samples in the cycle being filled (0 at a cycle boundary).
  long filled() const { return filled_; }

 private:
  long samples_per_cycle_;
  long next_cycle_ = 0;
  long filled_ = 0;
  CycleSummary current_;
  double pressure_sum_ = 0.0;
  bool has_pressure_ = false;
};

//! The cycles of a recorded periodic experiment (stroke, force and, if there, pressure), its time
//! axis taken as monotonic ns from 0. Throws daq::SessionError naming the experiment when it is
//! not periodic or its rate gives no whole number of samples per period.
std::vector<CycleSummary> SummariseExperiment(const daq::Experiment& experiment);

//! The cycles as a session metadata group `name` (one subgroup per cycle, "000000", ...) with the
//! verdict and tolerances as attributes, and back. CyclesFromGroup throws daq::SessionError naming
//! the group and attribute when one is missing.
daq::MetadataGroup CyclesGroup(const std::string& name, std::span<const CycleSummary> cycles,
                               const SteadyStateVerdict& verdict, const SteadyStateTolerances& tolerances);
std::vector<CycleSummary> CyclesFromGroup(const daq::MetadataGroup& group);
SteadyStateTolerances TolerancesFromGroup(const daq::MetadataGroup& group);

}  // namespace strut::rig
