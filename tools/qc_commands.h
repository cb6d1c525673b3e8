// Subcommands of the strut CLI for production QC (docs/qc.md); kept apart from commands.h so the
// QC wiring does not touch every command's translation unit.
#pragma once

#include <CLI/CLI.hpp>

namespace strut::tools {

//! `qc` with its `plan` and `history` subcommands.
void RegisterQcCommand(CLI::App& app);
//! Adds `qc` (the production-lot study) under the `bench` subcommand.
void RegisterBenchQc(CLI::App& bench);

}  // namespace strut::tools
