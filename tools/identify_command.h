// strut identify's options and its work, apart from the printing: the CLI (cmd_identify.cpp) and
// the Python package (python/, docs/python.md) bind the same options and call the same Fit().
#pragma once

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "model_options.h"
#include "strut/ident/session_fit.h"

namespace strut::tools {

struct IdentifyCommand {
  std::vector<std::string> sessions;
  ModelOptions model;
  std::string estimate;
  std::string json_path, report_path;
  int n = 0;                    // 0: by causality (ident::DefaultGridPoints)
  std::string scheme = "auto";  // auto: by causality (ident::DefaultScheme)
  std::string estimate_input = "auto";
  int input_harmonics = 20;
  bool no_progress = false;

  //! Reads the sessions, fits, writes --json and --report; logs (stderr), prints nothing.
  ident::SessionFit Fit() const;
  //! The JSON --json writes: the fit, the sessions and the exclusions.
  nlohmann::json Json(const ident::SessionFit& fit) const;
  //! Fit(), the report on stdout, the verdict as the exit code.
  void Run() const;
};

//! Adds identify's positional sessions and options to `command`, bound to `identify`.
void AddIdentifyOptions(CLI::App& command, IdentifyCommand& identify);

}  // namespace strut::tools
