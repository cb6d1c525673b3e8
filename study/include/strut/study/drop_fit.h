// What one drop adds to a shaker fit (`strut bench dropfit`, docs/drop-prediction.md "Drop records
// in the fit"). Per drawn unit: the standard shaker matrix fitted alone and with one drop of the
// same unit, both as strut identify fits them; theta3's sd side by side (the ratio), whether the
// truth is inside each fit's 95 % intervals, and the drop predicted from each fit against the
// truth's drop (the maximum stroke the shaker fit under-predicts).
#pragma once

#include <cmath>
#include <functional>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace strut::study {

struct DropFitOptions {
  int units = 10;
  unsigned long first_seed = 2000;
  double mass = 350.0, velocity = 0.5, duration = 10.0;  //!< kg, m/s at contact, s of the record
};

//! One fit of a unit.
struct DropFitFigures {
  std::string verdict;
  double theta3 = NAN, theta3_sd = NAN, z = NAN;  //!< z: (estimate - truth) / sd
  int inside = 0, estimated = 0;                  //!< estimated parameters with the truth inside the 95 % interval
  double max_stroke_error = NAN, peak_force_error = NAN;  //!< relative, the drop predicted from this fit
  bool max_stroke_inside = false;
  //! The max stroke error (relative) split over the estimated parameters, linearised: the
  //! prediction's gradient times each estimate's error (key, share), largest first.
  std::vector<std::pair<std::string, double>> max_stroke_terms;
  std::map<std::string, double> z_of;  //!< per estimated parameter, (estimate - truth) / sd
  double cpu = 0.0;                    //!< s of this thread for the fit
};

struct DropFitUnit {
  unsigned long seed = 0;
  double theta3_truth = 0.0;
  DropFitFigures alone, with_drop;
  double theta3_sd_ratio = 0.0;  //!< alone over with the drop
};

//! Alone or with the drop, over the units.
struct DropFitSide {
  int theta3_inside = 0, inside = 0, estimated = 0, at_floor = 0;
  double max_stroke_error_median = 0.0, max_stroke_error_largest = 0.0;  //!< relative; largest |error|
  long max_stroke_under = 0, max_stroke_inside = 0;  //!< under-predicted; truth inside the interval
  double cpu_median = 0.0;
};

struct DropFitStudy {
  std::vector<DropFitUnit> units;
  double ratio_median = 0.0, ratio_min = 0.0, ratio_max = 0.0;
  DropFitSide alone, with_drop;
  //! The shaker fit's max stroke error per parameter, median over the units (share, key), largest
  //! |share| first, with the median z of that parameter.
  std::vector<std::pair<double, std::string>> alone_terms;
  std::map<std::string, double> alone_median_z;
};

//! Runs the study; `on_unit` (may be empty) sees each unit as it ends.
DropFitStudy RunDropFitStudy(const DropFitOptions& options,
                             const std::function<void(const DropFitUnit&)>& on_unit = {});

}  // namespace strut::study
