#include "strut/batch/bench.h"

#include <fmt/format.h>

#include <chrono>
#include <filesystem>
#include <fstream>

namespace strut::batch {
namespace {

Plan BenchPlan(const BatchBenchOptions& o) {
  JobSpec job;
  job.name = "bench";
  job.kind = o.kind;
  job.units = o.units;
  job.first_seed = o.kind == "units" ? 1000 : 2000;
  if (o.kind == "confusion") job.effects = {"none", "viscous-damping"};
  Plan plan;
  plan.manifest = "strut bench batch";
  plan.jobs = {job};
  return plan;
}

EngineFigures Figures(const ResultsFolder& folder, const std::string& engine, double wall, int slots) {
  EngineFigures f;
  f.engine = engine;
  f.wall = wall;
  const Collected c = Collect(folder);
  if (!c.Complete())
    throw BatchError(fmt::format("{}: {} shards failed or missing; see {}", engine, c.failed.size() + c.missing.size(),
                                 folder.path()));
  for (const ShardId& id : c.done) f.work += folder.Record(id)->at("seconds").get<double>();
  f.shards = static_cast<int>(c.done.size());
  f.shards_per_minute = 60.0 * f.shards / wall;
  f.overhead_per_shard = (slots * wall - f.work) / f.shards;
  f.csv = Csv(nlohmann::json::parse(std::ifstream(folder.path() + "/results.json"))["jobs"][0]["results"]
                  .get<std::vector<nlohmann::json>>());
  return f;
}

}  // namespace

std::vector<EngineFigures> RunBatchBench(const BatchBenchOptions& o) {
  namespace fs = std::filesystem;
  const std::string stamp = fmt::format("{}", std::chrono::system_clock::now().time_since_epoch().count());
  std::vector<EngineFigures> out;
  {
    const ResultsFolder local = ResultsFolder::Prepare(fmt::format("{}/bench-local-{}", o.dir, stamp), BenchPlan(o), false);
    const auto start = std::chrono::steady_clock::now();
    RunLocal(local, local.Pending(), o.slots);
    out.push_back(Figures(local, "local", std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(),
                          o.slots));
  }
  if (o.slurm) {
    const ResultsFolder array = ResultsFolder::Prepare(fmt::format("{}/bench-slurm-{}", o.dir, stamp), BenchPlan(o), false);
    const auto start = std::chrono::steady_clock::now();
    SubmitArray(array, array.Pending(), o.slurm_options, ThisExecutable());
    WaitForArrays(array, o.poll, {});
    out.push_back(Figures(array, "slurm", std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(),
                          o.slots));
  }
  return out;
}

}  // namespace strut::batch
