// Options shared by every command that takes a model: --model, --input, --set, --params.
#pragma once

#include <CLI/CLI.hpp>
#include <string>

#include "strut/ident/model.h"

namespace strut::tools {

struct ModelOptions {
  std::string composition = "2dof";
  std::string input = "stroke";
  std::string assignments;  //!< --set NAME=VALUE[,NAME=VALUE...]
  std::string params_file;  //!< --params FILE

  //! Adds --model, --input, --set and --params to a subcommand.
  void Add(CLI::App& command);
  ident::Model BuildModel() const;
  //! The model's defaults, then --params, then --set (later wins).
  ident::ParameterSet Parameters(const ident::Model& model) const;
};

}  // namespace strut::tools
