// Subcommands of the strut CLI. Each Register* adds one subcommand to the app; tools/ only wires
// the libraries together, all real work lives in daq/, ident/, rig/, sim/, qc/, report/ and study/.
#pragma once

#include <CLI/CLI.hpp>
#include <memory>
#include <string>

namespace strut::tools {

void RegisterInfoCommand(CLI::App& app);
void RegisterPeriodicCommand(CLI::App& app);
void RegisterDemoCommand(CLI::App& app);
void RegisterBenchCommand(CLI::App& app);
void RegisterIdentifyCommand(CLI::App& app);
void RegisterDiscoverCommand(CLI::App& app);
//! Adds `discover` under the `bench` subcommand.
void RegisterBenchDiscover(CLI::App& bench);
//! Adds `units` (identification of drawn units) under the `bench` subcommand.
void RegisterBenchUnits(CLI::App& bench);
void RegisterBenchStrokeZero(CLI::App& bench);
//! Adds `confusion` (discovery on drawn units) under the `bench` subcommand.
void RegisterBenchConfusion(CLI::App& bench);
//! Adds `acquisition` (the CAN acquisition over UDP on loopback) under the `bench` subcommand.
void RegisterBenchAcquisition(CLI::App& bench);
void RegisterSimCommand(CLI::App& app);
void RegisterImportCommand(CLI::App& app);
//! `rig controller-status` (tools/cmd_rig.cpp).
void RegisterRigCommand(CLI::App& app);
//! Adds `run` (the test matrix on the rig, tools/cmd_rig_run.cpp) under the `rig` subcommand.
void RegisterRigRunCommand(CLI::App& rig);
void RegisterRecoverCommand(CLI::App& app);
//! `replay`: a recorded session played back as the rig's stream (tools/cmd_replay.cpp).
void RegisterReplayCommand(CLI::App& app);
//! Adds `replay` (replay speed, samples per CPU second) under the `bench` subcommand.
void RegisterBenchReplay(CLI::App& bench);
//! Adds `recorder` (streaming recorder throughput and CPU) under the `bench` subcommand.
void RegisterBenchRecorder(CLI::App& bench);
//! Adds `drop` (drop prediction from shaker fits of drawn units) under the `bench` subcommand.
void RegisterBenchDrop(CLI::App& bench);
void RegisterBenchDropFit(CLI::App& bench);
//! Adds `rig` (the standard matrix through the drivers on the simulated rig, tools/bench_rig.cpp) under `bench`.
void RegisterBenchRig(CLI::App& bench);
//! `batch`: a manifest's jobs in shards, local or as a Slurm array (tools/cmd_batch.cpp).
void RegisterBatchCommand(CLI::App& app);
//! Adds `batch` (the batch engines' shards per minute and overhead) under the `bench` subcommand.
void RegisterBenchBatch(CLI::App& bench);
//! Adds `served` (the two-process simulated rig run again and again, tools/bench_served.cpp) under `bench`.
void RegisterBenchServed(CLI::App& bench);
//! `predict drop`: drop-test prediction from a fit.
void RegisterPredictCommand(CLI::App& app);

//! A subcommand and the command object its options are bound to.
template <typename Command>
struct Subcommand {
  CLI::App* app;
  std::shared_ptr<Command> command;
};

//! Adds subcommand `name` under `parent` with a fresh `Command`, whose Run() is called when the
//! command line names the subcommand; the caller binds the options to the returned command.
template <typename Command>
Subcommand<Command> AddCommand(CLI::App& parent, const std::string& name, const std::string& description) {
  auto command = std::make_shared<Command>();
  CLI::App* app = parent.add_subcommand(name, description);
  app->callback([command] { command->Run(); });
  return {app, command};
}

}  // namespace strut::tools
