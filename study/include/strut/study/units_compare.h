// Two runs of `strut bench units` side by side (`--compare FILE`): per parameter the largest
// relative difference of the estimates and of z over the units both ran. A change that must leave
// the fits alone (a refactor, a build option) is checked by running the same units before and
// after it and comparing the JSON files.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "strut/study/units.h"

namespace strut::study {

//! One unit of a run as its JSON (`--json`) keeps it: what the comparison reads.
struct RunUnit {
  unsigned long seed = 0;
  std::map<std::string, double> z;         //!< (estimate - truth) / sd per parameter key
  std::map<std::string, double> estimate;  //!< per parameter key; empty in runs written before it was kept
};

//! The units of one run of the study.
struct UnitsRun {
  std::string source;  //!< the file it was read from ("this run" for one made here); names it in errors
  std::vector<RunUnit> units;
};

//! The units of `study` as a run (`source` "this run").
UnitsRun ToRun(const UnitsStudy& study);
//! Reads the units ("units": [{"seed", "z", "estimate"}]) of a `strut bench units --json` file.
//! Throws std::invalid_argument naming the file (and the unit) when it cannot be read, is no JSON
//! or lacks a unit's seed or z.
UnitsRun ReadUnitsRun(const std::string& path);

//! |a - b| / max(|a|, |b|): 0 when a == b (both 0 included), infinity when either is not finite
//! and they differ.
double RelativeDifference(double a, double b);

//! One parameter over the units both runs have.
struct ParameterDifference {
  std::string key;
  long units = 0;             //!< units in which both runs have its z
  double z = 0.0;             //!< largest relative difference of z
  unsigned long z_seed = 0;   //!< the unit where it is (the first unit when none differs)
  long estimate_units = 0;    //!< units in which both runs have its estimate (0: not compared)
  double estimate = 0.0;      //!< largest relative difference of the estimates
  unsigned long estimate_seed = 0;
};

struct UnitsComparison {
  double tolerance = 0.0;
  long units = 0;  //!< units (seeds) in both runs
  std::vector<unsigned long> only_before, only_now;  //!< seeds in one run only (not compared)
  bool before_has_estimates = false;  //!< the earlier run kept estimates (else z alone is compared)
  std::vector<ParameterDifference> parameters;  //!< by key
  //! What one run has and the other lacks in a unit both ran ("unit 1003: theta4's z only in the
  //! earlier run"): a changed estimated set, itself a difference.
  std::vector<std::string> missing;
  //! Parameters whose estimate or z differs by more than the tolerance (each counted once per figure).
  long exceeded = 0;
  //! Nothing beyond the tolerance, nothing missing, and at least one unit compared.
  bool same() const { return exceeded == 0 && missing.empty() && units > 0; }
};

//! Compares `now` with `before` unit by unit (by seed): per parameter key the largest relative
//! difference of z and, where both runs kept them, of the estimates. `tolerance`: relative.
UnitsComparison CompareUnits(const UnitsRun& before, const UnitsRun& now, double tolerance);

}  // namespace strut::study
