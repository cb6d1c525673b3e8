// Running a batch's shards: on this machine's threads (the default engine), or one array task's
// shards (what a Slurm task, an HTCondor job or a Kubernetes pod of an indexed Job runs).
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "strut/batch/results.h"

namespace strut::batch {

//! Where a batch stands: shards with a result, failed, running, and the time to the end.
struct Progress {
  int total = 0, done = 0, failed = 0, running = 0;
  double elapsed = 0.0;  //!< s since this run started
  double eta = -1.0;     //!< s to the end, estimated from this run's shards; < 0 unknown
};
//! "[#######.............]  12/40 done, 1 failed, 2 running, 3m20s to go".
std::string ProgressLine(const Progress& p);

//! Runs `shards` of the folder's plan on `threads` threads, each shard's record written as it ends.
//! `on_progress` (may be empty) sees the progress at the start and after every shard, one call at a
//! time. A failed shard is recorded and the others go on.
void RunLocal(const ResultsFolder& folder, const std::vector<ShardId>& shards, int threads,
              const std::function<void(const Progress&)>& on_progress = {});

//! Runs the given shards one after the other in this process (an array task), skipping those that
//! already have a successful record (a task run again must not run a finished shard again).
void RunShards(const ResultsFolder& folder, const std::vector<ShardId>& shards);

}  // namespace strut::batch
