// strut batch: a manifest's jobs split into shards, run on this machine's threads or as a Slurm job
// array, resumed where they stopped, merged into one table (docs/batch.md).
//   strut batch MANIFEST.toml [--out DIR] [--force] [--threads 2] [--no-progress]
//   strut batch MANIFEST.toml --slurm [--partition P] [--time-limit T] [--shards-per-task N]
//                             [--sbatch-arg ARG]... [--no-wait] [--poll S]
//   strut batch --collect DIR
//   strut batch --task-file FILE [--task-index N]   (what an array task runs)
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>

#include "commands.h"
#include "option_checks.h"
#include "output_files.h"
#include "strut/batch/engine.h"
#include "strut/batch/slurm.h"

namespace strut::tools {
namespace {
namespace fs = std::filesystem;

struct BatchCommand {
  std::string manifest, out, collect, task_file;
  int task_index = -1;
  bool force = false, no_progress = false;
  int threads = 2;
  bool slurm = false, no_wait = false;
  double poll = 5.0;
  batch::SlurmOptions slurm_options;

  void Run() {
    if (!task_file.empty()) return RunTask();
    if (!collect.empty()) return Report(batch::ResultsFolder::Open(collect));
    if (manifest.empty()) throw std::invalid_argument("batch: give a manifest (strut batch MANIFEST.toml), or --collect DIR");
    batch::Plan plan = batch::ReadManifest(manifest);
    const std::string dir = out.empty() ? (fs::path(manifest).replace_extension(".batch")).string() : out;
    const batch::ResultsFolder folder = batch::ResultsFolder::Prepare(dir, std::move(plan), force);
    const std::vector<batch::ShardId> pending = folder.Pending();
    spdlog::info("{}: {} shards, {} to run, results in {}", manifest, folder.plan().Shards(), pending.size(),
                 folder.path());
    if (!pending.empty() && slurm) {
      const batch::Submission s = batch::SubmitArray(folder, pending, slurm_options, batch::ThisExecutable());
      spdlog::info("submitted Slurm job {}: {} array tasks ({})", s.job_id, s.tasks, s.script);
      if (no_wait) {
        spdlog::info("collect the results with: strut batch --collect {}", folder.path());
        return;
      }
      Wait(folder);
    } else if (!pending.empty()) {
      const bool tty = !no_progress && isatty(fileno(stderr));
      batch::RunLocal(folder, pending, threads, [&](const batch::Progress& p) { Show(p, tty); });
      if (tty) std::fprintf(stderr, "\n");
    }
    Report(folder);
  }

  static void Show(const batch::Progress& p, bool tty) {
    if (tty)
      std::fprintf(stderr, "\r%s   ", batch::ProgressLine(p).c_str());
    else if (p.running == 0 || p.done + p.failed > 0)
      spdlog::info("{}", batch::ProgressLine(p));
  }

  //! Until every shard has its record or the array has left Slurm's queue.
  void Wait(const batch::ResultsFolder& folder) const {
    const bool tty = !no_progress && isatty(fileno(stderr));
    int last = -1;
    batch::WaitForArrays(folder, poll, [&](const batch::Progress& p) {
      if (tty || p.done != last) Show(p, tty);
      last = p.done;
    });
    if (tty) std::fprintf(stderr, "\n");
  }

  void RunTask() const {
    int index = task_index;
    if (index < 0) {
      const char* env = std::getenv("SLURM_ARRAY_TASK_ID");
      if (!env) throw std::invalid_argument("--task-file: give --task-index (or run as an array task, SLURM_ARRAY_TASK_ID)");
      index = std::atoi(env);
    }
    const batch::ResultsFolder folder = batch::ResultsFolder::Open(fs::path(task_file).parent_path().parent_path());
    batch::RunShards(folder, batch::TaskShards(folder.plan(), task_file, index));
  }

  static void Report(const batch::ResultsFolder& folder) {
    const batch::Collected c = batch::Collect(folder);
    for (const auto& [job, table] : c.tables) std::cout << table << "\n";
    spdlog::info("{}: {} of {} shards done; merged into {}/JOB.csv, JOB.txt, results.json", folder.path(),
                 c.done.size(), folder.plan().Shards(), folder.path());
    for (const batch::ShardId& id : c.failed) spdlog::error("shard {} failed: {}", id.Text(), c.errors.at(id));
    for (const batch::ShardId& id : c.missing) spdlog::error("shard {} is missing (never ran, or was stopped)", id.Text());
    if (c.Complete()) return;
    const std::vector<std::string> active = fs::exists(folder.path() + "/slurm/jobs") ? batch::ActiveJobs(folder)
                                                                                         : std::vector<std::string>{};
    if (!active.empty())
      spdlog::warn("Slurm job {} is still in the queue: collect again later", active.front());
    else
      spdlog::warn("run the same strut batch again to run the {} failed and missing shards alone",
                   c.failed.size() + c.missing.size());
    throw ExitCode(kExitIncomplete);
  }
};

}  // namespace

void RegisterBatchCommand(CLI::App& app) {
  auto [sub, command] = AddCommand<BatchCommand>(
      app, "batch",
      "Run a manifest's jobs (identify, discover, qc over sessions; the confusion, units, qc-lot and drop studies) split into "
      "shards, on this machine's threads or as a Slurm job array; a finished shard is never run again (docs/batch.md). "
      "Exit code 7 when shards failed or are missing.");
  sub->add_option("manifest", command->manifest, "The batch manifest (TOML, docs/batch.md).")->check(CLI::ExistingFile);
  sub->add_option("--out", command->out, "The results folder (default: the manifest's name with .batch); an existing "
                                          "one of the same jobs goes on where it stopped.");
  sub->add_flag("--force", command->force, "Discard the results of other jobs in --out.");
  sub->add_option("--threads", command->threads, "Shards run side by side on this machine.")
      ->check(Between(1, 256))
      ->capture_default_str();
  sub->add_flag("--no-progress", command->no_progress, "No progress bar (it is shown only when stderr is a terminal).");
  sub->add_flag("--slurm", command->slurm, "Run the shards as a Slurm job array (sbatch) on a folder the nodes share.");
  sub->add_option("--partition", command->slurm_options.partition, "With --slurm: the partition (default: the cluster's).");
  sub->add_option("--time-limit", command->slurm_options.time_limit, "With --slurm: each task's time limit, as sbatch --time takes it.");
  sub->add_option("--shards-per-task", command->slurm_options.shards_per_task, "With --slurm: the shards each array task runs.")
      ->check(Between(1, 100000))
      ->capture_default_str();
  sub->add_option("--sbatch-arg", command->slurm_options.sbatch_args,
                  "With --slurm: a further sbatch argument (repeat), e.g. --sbatch-arg=--account=lab.");
  sub->add_flag("--no-wait", command->no_wait, "With --slurm: return after submitting; strut batch --collect DIR later.");
  sub->add_option("--poll", command->poll, "With --slurm: seconds between looks at the results while waiting.")
      ->check(Between(0.1, 3600.0))
      ->capture_default_str();
  sub->add_option("--collect", command->collect, "Merge what a results folder holds and name the shards missing.")
      ->check(CLI::ExistingDirectory);
  sub->add_option("--task-file", command->task_file, "Run one array task's line of this tasks file (what the array "
                                                     "tasks run).")
      ->check(CLI::ExistingFile);
  sub->add_option("--task-index", command->task_index, "The task's line (default: SLURM_ARRAY_TASK_ID).");
}

}  // namespace strut::tools
