// The drop prediction for people and programs (`strut predict drop`, docs/drop-prediction.md): the
// table of figures, the JSON record and the self-contained HTML report, in the reports' units
// (mm, kN, MPa; times in s).
#pragma once

#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "strut/sim/drop_prediction.h"

namespace strut::report {

//! One predicted drop and what it is compared with.
struct DropComparison {
  std::string fit_path;     //!< the fit's JSON
  std::string model;        //!< the fitted model's composition
  std::string fit_verdict;  //!< the fit's verdict ("" unknown)
  double mass = 0.0;             //!< kg
  double impact_velocity = 0.0;  //!< m/s
  sim::DropPredictionOptions options;
  std::map<std::string, double> scale;  //!< what-if factors by parameter key (empty: none)
  sim::WhatIfDrop prediction;           //!< predicted, and the fit unscaled when scaled
  std::optional<sim::MeasuredDrop> measured;
  std::string measured_session, measured_experiment;  //!< where the measured drop is from
  std::vector<sim::MissingPhysics> missing;            //!< physics the truth has, the fitted model not
};

//! The figures side by side: figure, predicted, the interval, the fit unscaled (when scaled),
//! measured and the relative error (when compared); "-" where a value is not defined.
struct DropTable {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
};
DropTable DropFigureTable(const DropComparison& drop);

//! The record of `strut predict drop --json` (docs/drop-prediction.md): inputs, the figures in SI
//! with their intervals, the measured figures with the relative errors and whether each lies
//! inside its interval, the missing physics and the timing. Non-finite numbers are null.
nlohmann::json DropJson(const DropComparison& drop);

//! The HTML report: what was predicted how, the table, the missing physics, the impact and the
//! whole record plotted (predicted, unscaled, measured) and what the intervals leave out.
//! Throws std::runtime_error naming the path when it cannot write.
void WriteDropReport(const DropComparison& drop, const std::string& path);

}  // namespace strut::report
