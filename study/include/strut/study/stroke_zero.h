// The top-out reference on drawn units (`strut bench stroke-zero`, docs/rig-run.md "The top-out
// reference"): each unit drawn as `strut bench units` draws it, served in this process
// (sim::SimulatedRigFactory: the real drivers on loopback, accelerated), the reference run by the
// matrix runner with no experiments after it, and the stroke zero it records against the truth
// the unit's LVDT reads at full extension.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "strut/rig/matrix_runner.h"
#include "strut/rig/top_out.h"
#include "strut/sim/truth.h"
#include "strut/study/units.h"

namespace strut::study {

//! The reference of one truth, recorded into the session at `path` (replaced): the run's report
//! (RunReport::top_out holds the zero, or top_out_failure why none). `speed`: simulated seconds
//! per wall second of the served rig.
rig::RunReport RunTopOutReference(const sim::Truth& truth, const rig::TopOutOptions& options, double speed,
                                  const std::string& path);

struct StrokeZeroOptions {
  UnitsOptions draw;  //!< the units (units, first_seed, base, servo, shipped_calibration) as bench units draws them
  rig::TopOutOptions top_out;
  double speed = 100.0;
  std::string scratch;  //!< the session file each unit's reference is recorded to (removed after)
};

struct StrokeZeroUnit {
  unsigned long seed = 0;
  double theta12 = 0.0;  //!< the drawn stroke offset, m
  double truth = 0.0;    //!< the LVDT's reading at full extension, m (theta12 through its gain and zero errors)
  bool found = false;
  std::string failure;
  double zero = 0.0, sd = 0.0, fit_sd = 0.0, stiffness = 0.0;
  double wall = 0.0;  //!< s
  double error() const { return zero - truth; }
};

struct StrokeZeroStudy {
  std::vector<StrokeZeroUnit> units;
  long found = 0;
  double mean_error = 0.0, sd_error = 0.0, largest_error = 0.0;  //!< m, over the found units
  double mean_error_theta12 = 0.0, sd_error_theta12 = 0.0;        //!< m, against theta12 itself
  double median_sd = 0.0;                                          //!< m, of the recorded sds
  long within_1sd = 0, within_2sd = 0;                             //!< |error| <= 1 sd, <= 1.96 sd
  double wall_median = 0.0;
};

//! Unit `u` (seed draw.first_seed + u), the unit `strut bench units` fits under that seed.
StrokeZeroUnit ReferenceDrawnUnit(const StrokeZeroOptions& options, int u);
StrokeZeroStudy SummariseStrokeZero(std::vector<StrokeZeroUnit> units);
//! What the bench prints: a line per unit and the summary.
std::string StrokeZeroLine(const StrokeZeroUnit& unit);
std::string StrokeZeroSummary(const StrokeZeroOptions& options, const StrokeZeroStudy& study);

}  // namespace strut::study
