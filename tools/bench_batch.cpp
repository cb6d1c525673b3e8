// strut bench batch: one study through the local engine and through Slurm on this machine (batch::
// RunBatchBench): shards per minute side by side, the engine's overhead per shard against a shard.
#include <fmt/format.h>

#include <iostream>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "option_checks.h"
#include "output_files.h"
#include "strut/batch/bench.h"

namespace strut::tools {
namespace {

struct BenchBatch {
  batch::BatchBenchOptions options;
  std::string json_path;

  void Run() {
    CheckOutputPath("--json", json_path, {});
    if (options.dir.empty()) options.dir = ".";
    const std::vector<batch::EngineFigures> figures = batch::RunBatchBench(options);
    std::cout << fmt::format("the {} study, {} shards of one unit, {} at once:\n", options.kind, figures.front().shards,
                             options.slots);
    std::cout << fmt::format("  {:<7} {:>8} {:>12} {:>14} {:>18} {:>12}\n", "engine", "wall s", "shards/min",
                             "shard work s", "overhead/shard s", "of a shard");
    nlohmann::json rows = nlohmann::json::array();
    for (const batch::EngineFigures& f : figures) {
      const double mean = f.work / f.shards;
      std::cout << fmt::format("  {:<7} {:>8.2f} {:>12.1f} {:>14.3f} {:>18.3f} {:>11.0f}%\n", f.engine, f.wall,
                               f.shards_per_minute, mean, f.overhead_per_shard, 100.0 * f.overhead_per_shard / mean);
      rows.push_back({{"engine", f.engine}, {"shards", f.shards}, {"wall", f.wall}, {"work", f.work},
                      {"shards_per_minute", f.shards_per_minute}, {"overhead_per_shard", f.overhead_per_shard}});
    }
    if (figures.size() == 2) {
      std::cout << fmt::format("slurm / local shards per minute: {:.2f}; the merged tables {}\n",
                               figures[1].shards_per_minute / figures[0].shards_per_minute,
                               figures[1].csv == figures[0].csv ? "are the same bit for bit" : "DIFFER");
    }
    if (!json_path.empty()) WriteJsonOutput(json_path, nlohmann::json{{"engines", rows}});
  }
};

}  // namespace

void RegisterBenchBatch(CLI::App& bench) {
  auto [sub, command] = AddCommand<BenchBatch>(
      bench, "batch",
      "A study through strut batch's local engine and, with --slurm, as a Slurm job array on this machine: shards "
      "per minute side by side and the overhead per shard (docs/batch.md).");
  sub->add_option("--kind", command->options.kind, "The study: confusion (a discover run a shard) or units (a fit).")
      ->check(CLI::IsMember({"confusion", "units"}))
      ->capture_default_str();
  sub->add_option("--units", command->options.units, "Drawn units (per effect for confusion: none, viscous-damping).")
      ->check(Between(1, 10000))
      ->capture_default_str();
  sub->add_option("--slots", command->options.slots, "Shards at once: the local threads, and what the Slurm node runs.")
      ->check(Between(1, 256))
      ->capture_default_str();
  sub->add_flag("--slurm", command->options.slurm, "Also run the study as a Slurm job array (sbatch on PATH).");
  sub->add_option("--partition", command->options.slurm_options.partition, "With --slurm: the partition.");
  sub->add_option("--shards-per-task", command->options.slurm_options.shards_per_task,
                  "With --slurm: the shards each array task runs (a task's start is shared by them).")
      ->check(Between(1, 100000))
      ->capture_default_str();
  sub->add_option("--sbatch-arg", command->options.slurm_options.sbatch_args, "With --slurm: a further sbatch argument.");
  sub->add_option("--dir", command->options.dir,
                  "An existing folder for the two results folders (shared with the nodes; default: this one).")
      ->check(CLI::ExistingDirectory);
  sub->add_option("--json", command->json_path, "Also write the figures as JSON to this file.");
}

}  // namespace strut::tools
