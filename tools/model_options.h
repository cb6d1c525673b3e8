// Options shared by every command that takes a model: --model, --input, --set, --params.
#pragma once

#include <CLI/CLI.hpp>
#include <string>

#include "strut/ident/model.h"
#include "strut/ident/session_fit.h"

namespace strut::tools {

struct ModelOptions {
  std::string composition = "2dof";
  std::string input = "stroke";
  std::string assignments;  //!< --set NAME=VALUE[,NAME=VALUE...]
  std::string params_file;  //!< --params FILE
  std::vector<std::string> exclude;  //!< --exclude LABEL[:CHANNEL],... (commands that read sessions)
  std::string calibration;           //!< --calibration force=0.2%,pressure=0.2%,stroke=0.1% | none (empty: the lab default)

  //! Adds --model, --input, --set and --params to a subcommand.
  void Add(CLI::App& command);
  ident::Model BuildModel() const;
  //! The model's defaults, then --params, then --set (later wins).
  ident::ParameterSet Parameters(const ident::Model& model) const;
  //! Adds --exclude and --calibration to a subcommand that fits sessions.
  void AddSessionFit(CLI::App& command);
  //! The fit options these settings make (model, causality, file, assignments, exclusions,
  //! calibration; grid n). Throws std::invalid_argument for a bad --calibration.
  ident::SessionFitOptions FitOptions(int n) const;
};

//! Adds --n, the fit's grid points per period (0, the default: by causality), to a subcommand that
//! fits sessions.
void AddFitGridOption(CLI::App& command, int& n);

}  // namespace strut::tools
