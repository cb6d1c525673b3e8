// Subcommands of the strut CLI for production QC (docs/qc.md); kept apart from commands.h so the
// QC wiring does not touch every command's translation unit.
#pragma once

#include <CLI/CLI.hpp>
#include <string>

#include "strut/ident/session_fit.h"
#include "strut/qc/decision.h"

namespace strut::tools {

//! What `strut qc` decided, and the fit it decided on (empty when no fit was made).
struct QcOutcome {
  qc::Decision decision;
  ident::SessionFit fit;
};

//! strut qc's options and its work, apart from the printing: the CLI and the Python package
//! (python/, docs/python.md) bind the same options and call the same Decide().
struct QcCommand {
  std::string session, reference, json_path, report_path, db_path, time;

  //! Checks the outputs, decides, writes --json and --report and records in --db; logs (stderr),
  //! prints nothing. Throws for bad options and an unreadable reference or history.
  QcOutcome Decide() const;
  //! Decide(), the table on stdout, the verdict as the exit code: every error ends with exit code
  //! 2 (UNDECIDED), as 1 would read as FAIL.
  void Run() const;
};

//! Adds qc's positional session and options to `command`, bound to `qc`.
void AddQcOptions(CLI::App& command, QcCommand& qc);

//! `qc` with its `plan` and `history` subcommands.
void RegisterQcCommand(CLI::App& app);
//! Adds `qc` (the production-lot study) under the `bench` subcommand.
void RegisterBenchQc(CLI::App& bench);

}  // namespace strut::tools
