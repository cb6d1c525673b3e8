// strut discover's options and its work, apart from the printing: the CLI (cmd_discover.cpp) and
// the Python package (python/, docs/python.md) bind the same options and call the same Discover().
#pragma once

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

#include "model_options.h"
#include "strut/ident/discover.h"

namespace strut::tools {

struct DiscoverCommand {
  std::vector<std::string> sessions;
  ModelOptions model;
  std::string json_path, report_path;
  int n = 0;  // 0: by causality (ident::DefaultGridPoints)
  int threads = 2;

  //! Reads the sessions, discovers, writes --json and --report; logs (stderr), prints nothing.
  ident::DiscoveryResult Discover() const;
  //! Discover(), the conclusion and the steps on stdout.
  void Run() const;
};

//! Adds discover's positional sessions and options to `command`, bound to `discover`.
void AddDiscoverOptions(CLI::App& command, DiscoverCommand& discover);

}  // namespace strut::tools
