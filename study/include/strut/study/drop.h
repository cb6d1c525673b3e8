// Drop-test prediction on drawn units (`strut bench drop`, docs/drop-prediction.md). Per unit: the
// standard shaker matrix simulated and fitted as strut identify would, the fit read back from its
// JSON, a drop of the unit's truth, and the drop predicted from the fit: errors of every figure,
// whether the truth is inside the 95 % intervals, the prediction's time. With effects the truth has
// physics the fitted 2 dof model lacks, and each unit says which figures that physics moves.
#pragma once

#include <functional>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <utility>
#include <vector>

#include "strut/ident/estimator.h"

namespace strut::study {

struct DropOptions {
  int units = 10;
  unsigned long first_seed = 2000;
  double mass = 350.0, velocity = 0.5, duration = 30.0;  //!< kg, m/s at contact, s from contact
  std::vector<std::string> effects;  //!< physics the truth has and the fitted model lacks
};

//! One figure of one unit's predicted drop against the truth's.
struct DropFigureError {
  std::string name;
  bool time = false;    //!< a time: the error is a difference in s (else relative)
  double error = 0.0;
  bool inside = false;  //!< the truth inside the 95 % interval
  bool has_interval = false;  //!< the interval is finite (counted for the coverage)
};

struct DropUnit {
  unsigned long seed = 0;
  ident::FitVerdict verdict = ident::FitVerdict::kNotConverged;
  std::vector<DropFigureError> figures;  //!< the measured figures with a finite error
  //! Relative errors of the peak force, the max stroke and the final stroke.
  double peak_force_error = 0.0, max_stroke_error = 0.0, final_stroke_error = 0.0;
  bool peak_force_inside = false, max_stroke_inside = false;
  std::vector<std::pair<std::string, std::string>> missing_physics;  //!< term, the figures it moves
  double cpu = 0.0, wall = 0.0;                    //!< s, the prediction alone
  double intervals_cpu = 0.0, intervals_wall = 0.0;  //!< s, the prediction with intervals
  int simulations = 0;                             //!< runs of the prediction with intervals
};

//! One figure over the units.
struct DropFigureSummary {
  std::string name;
  bool time = false;
  double median_abs_error = 0.0, max_abs_error = 0.0;
  long inside = 0, counted = 0;  //!< units with an interval, and of them those holding the truth
};

struct DropStudy {
  std::vector<DropUnit> units;
  std::vector<DropFigureSummary> figures;
  int fits = 0, at_floor = 0, within5 = 0;  //!< within5: peak force and max stroke both within 5 %
  double cpu_median = 0.0, wall_median = 0.0, intervals_cpu_median = 0.0, intervals_wall_median = 0.0;
};

//! Unit `u` (seed first_seed + u): what RunDropStudy predicts for it, so that a study split into
//! ranges of units (strut batch) gives the same units.
DropUnit PredictDropUnit(const DropOptions& options, int u);
//! The study's figures from its units in unit order (what RunDropStudy gives for them).
DropStudy SummariseDrop(std::vector<DropUnit> units);

//! A unit in full as a batch shard keeps it, and back (doubles round-trip).
nlohmann::json DropUnitJson(const DropUnit& unit);
DropUnit DropUnitFromJson(const nlohmann::json& j);

//! What `strut bench drop` prints: the heading, a line per unit, the summary.
std::string DropHeading(const DropOptions& options);
std::string DropUnitLine(const DropUnit& unit);
std::string DropSummary(const DropOptions& options, const DropStudy& study);

//! Runs the study; `on_unit` (may be empty) sees each unit as it ends.
DropStudy RunDropStudy(const DropOptions& options, const std::function<void(const DropUnit&)>& on_unit = {});

}  // namespace strut::study
