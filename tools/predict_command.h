// strut predict drop's options and its work, apart from the printing: the CLI (cmd_predict.cpp) and
// the Python package (python/, docs/python.md) bind the same options and call the same Predict().
#pragma once

#include <CLI/CLI.hpp>
#include <optional>
#include <string>
#include <vector>

#include "strut/report/drop_report.h"
#include "strut/sim/drop_prediction.h"

namespace strut::tools {

struct PredictDropCommand {
  std::string fit_path;
  std::optional<double> mass, velocity, duration;
  std::string moving_mass = "dropped";
  std::string compare_path, experiment_label;
  std::vector<std::string> scales;
  std::string json_path, report_path;
  sim::DropPredictionOptions options;
  bool no_intervals = false;

  //! Reads the fit (and the recorded drop), predicts, writes --json and --report; logs (stderr),
  //! prints nothing.
  report::DropComparison Predict() const;
  //! Predict(), the figures on stdout.
  void Run() const;
};

//! Adds predict drop's options to `command`, bound to `predict`.
void AddPredictDropOptions(CLI::App& command, PredictDropCommand& predict);

}  // namespace strut::tools
