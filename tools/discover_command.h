// strut discover's options and its work, apart from the printing: the CLI (cmd_discover.cpp) and
// the Python package (python/, docs/python.md) bind the same options and call the same Discover().
#pragma once

#include <CLI/CLI.hpp>
#include <optional>
#include <string>
#include <vector>

#include "model_options.h"
#include "truth_options.h"
#include "strut/ident/discover.h"
#include "strut/rig/safety.h"

namespace strut::tools {

struct DiscoverCommand {
  std::vector<std::string> sessions;
  ModelOptions model;
  std::string json_path, report_path;
  //! The test that decides the first ambiguity, as a matrix file, checked against `limits_path`'s limits.
  std::string propose_test_path, limits_path;
  //! --decide: the session the decisive test is recorded to on the rig (`rig_spec`, `daq_spec`;
  //! a simulated rig's truth and speed), then every rival model fitted with it.
  std::string decide_path, rig_spec, daq_spec;
  std::optional<double> speed;
  bool force = false;
  TruthOptions truth;
  int n = 0;  // 0: by causality (ident::DefaultGridPoints)
  int threads = 2;

  //! Reads the sessions, discovers, writes --json and --report; logs (stderr), prints nothing.
  ident::DiscoveryResult Discover() const;
  //! Discover(), the conclusion and the steps on stdout.
  void Run() const;
  //! Writes the first ambiguity's decisive test to `path` as a matrix file; false when nothing is ambiguous.
  bool WriteProposedTest(const ident::DiscoveryResult& result, const rig::SafetyConfig& limits,
                         const std::string& path) const;
  //! --propose-test, or beside --decide's session.
  std::string MatrixPath() const;
};

//! Adds discover's positional sessions and options to `command`, bound to `discover`.
void AddDiscoverOptions(CLI::App& command, DiscoverCommand& discover);

}  // namespace strut::tools
