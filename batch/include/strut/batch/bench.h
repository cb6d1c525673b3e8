// `strut bench batch` (docs/batch.md, "Figures"): one study through the local engine and, when
// asked, through Slurm on the same machine: shards per minute, the time a shard's own work takes,
// and the engine's overhead per shard beside it.
#pragma once

#include <string>
#include <vector>

#include "strut/batch/slurm.h"

namespace strut::batch {

struct BatchBenchOptions {
  std::string kind = "confusion";  //!< confusion (a discover run a shard) or units (an identify run)
  int units = 4;                   //!< per effect for confusion (effects none and viscous-damping)
  int slots = 2;                   //!< shards at once: the local threads, and what the Slurm node runs
  bool slurm = false;
  SlurmOptions slurm_options;
  std::string dir;  //!< an existing folder the results folders go in (shared with the nodes)
  double poll = 0.5;
};

struct EngineFigures {
  std::string engine;  //!< "local" or "slurm"
  int shards = 0;
  double wall = 0.0;          //!< s, from the start to the last record
  double work = 0.0;          //!< s, the shards' own time summed (their records)
  double shards_per_minute = 0.0;
  //! (slots x wall - work) / shards: what the engine adds to each shard (start, scheduling, idle tail).
  double overhead_per_shard = 0.0;
  std::string csv;  //!< the merged table (to check both engines give the same)
};

//! Runs the bench; throws BatchError when a folder cannot be made or Slurm refuses the array.
std::vector<EngineFigures> RunBatchBench(const BatchBenchOptions& options);

}  // namespace strut::batch
