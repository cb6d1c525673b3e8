// The Slurm engine (docs/batch.md): the pending shards become one job array; each array task runs
// `strut batch --task-file FILE --task-index N` (the same binary, on the shared results folder),
// which reads the plan and runs its line of shards. strut writes the script, submits it with
// sbatch, and watches the shard records (and squeue) until the array has left the queue.
#pragma once

#include <string>
#include <vector>

#include <functional>

#include "strut/batch/engine.h"
#include "strut/batch/results.h"

namespace strut::batch {

struct SlurmOptions {
  std::string partition;   //!< "" the cluster's default
  std::string time_limit;  //!< per task, as sbatch --time takes it ("" the partition's)
  int shards_per_task = 1;
  std::vector<std::string> sbatch_args;  //!< passed to sbatch as they are (--account=..., --mem=...)
};

//! What was submitted.
struct Submission {
  std::string job_id;  //!< Slurm's id of the array
  std::string script, tasks_file;
  int tasks = 0;
};

//! The tasks file: line i the shards of array task i ("job/3 job/4").
std::string TasksText(const std::vector<ShardId>& shards, int shards_per_task);
//! The shards of line `index` of a tasks file; throws BatchError naming the file.
std::vector<ShardId> TaskShards(const Plan& plan, const std::string& tasks_file, int index);

//! The sbatch script of an array of `tasks` tasks that runs `strut` on `tasks_file`.
std::string SbatchScript(const ResultsFolder& folder, const std::string& tasks_file, int tasks,
                         const SlurmOptions& options, const std::string& strut);

//! Writes slurm/array-N.tasks and slurm/array-N.sh in the folder for `shards` and submits them with
//! sbatch; the job's id is appended to slurm/jobs. Throws BatchError with sbatch's message.
Submission SubmitArray(const ResultsFolder& folder, const std::vector<ShardId>& shards, const SlurmOptions& options,
                       const std::string& strut);

//! The folder's array jobs that Slurm still has pending or running (squeue); empty when none.
std::vector<std::string> ActiveJobs(const ResultsFolder& folder);

//! Watches the folder's shard records every `poll` seconds until every shard has one or the
//! folder's arrays have left Slurm's queue; `on_progress` (may be empty) sees each look.
void WaitForArrays(const ResultsFolder& folder, double poll, const std::function<void(const Progress&)>& on_progress);

//! This process's executable (what the array tasks run).
std::string ThisExecutable();

}  // namespace strut::batch
