// The batch library alone (docs/batch.md): shard ranges cover every item once, the plan reads back
// as written, records flatten into CSV columns, the tasks file and the sbatch script of an array,
// the local engine's progress (shards done, failed and running, the time to go).
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <mutex>
#include <vector>
#include <set>

#include "strut/batch/engine.h"
#include "strut/batch/plan.h"
#include "strut/batch/results.h"
#include "strut/batch/slurm.h"
#include "test_support.h"

namespace strut::batch {
namespace {

TEST(BatchPlan, ShardsCoverEveryItemOnceWhateverTheSplit) {
  test::TempDir dir;
  std::ofstream(dir.file("m.toml")) << "[[job]]\nkind = \"confusion\"\nunits = 7\neffects = [\"none\", \"real-gas\"]\n"
                                       "per_shard = 3\n\n[[job]]\nname = \"u\"\nkind = \"units\"\nunits = 5\n";
  const Plan plan = ReadManifest(dir.file("m.toml"));
  ASSERT_EQ(plan.jobs.size(), 2u);
  const JobSpec& c = plan.jobs[0];
  EXPECT_EQ(c.name, "confusion");
  EXPECT_EQ(c.first_seed, 2000u);  // bench confusion's default
  EXPECT_EQ(plan.jobs[1].first_seed, 1000u);  // bench units'
  EXPECT_EQ(c.Items(), 14);
  EXPECT_EQ(c.Shards(), 5);
  std::set<int> items;
  for (int s = 0; s < c.Shards(); ++s)
    for (int k = c.ShardFirst(s); k < c.ShardFirst(s) + c.ShardCount(s); ++k) EXPECT_TRUE(items.insert(k).second) << k;
  EXPECT_EQ(items.size(), 14u);
  EXPECT_EQ(*items.rbegin(), 13);
  EXPECT_EQ(plan.Shards(), 10);
  EXPECT_EQ(ParseShard(plan, "u/4").shard, 4);
  EXPECT_THROW(ParseShard(plan, "u/5"), BatchError);
  EXPECT_THROW(ParseShard(plan, "nope/0"), BatchError);
  Plan back = PlanFromJson(ToJson(plan));
  EXPECT_TRUE(SameJobs(back, plan));
  back.jobs[1].units = 6;
  EXPECT_FALSE(SameJobs(back, plan));
}

TEST(BatchResults, RecordsFlattenIntoColumnsWithoutTiming) {
  const nlohmann::json a = {{"seed", 1000}, {"found", {"a", "b"}}, {"z", {{"theta3", 0.5}, {"theta4", -1.25}}},
                            {"signal", {{"rms", 1.5}, {"channel", "force"}}}, {"note", "x, \"y\""},
                            {"timing", {{"seconds", 0.3}}}};
  const nlohmann::json b = {{"seed", 1001}, {"found", nlohmann::json::array()}, {"extra", nullptr}};
  EXPECT_EQ(Csv({a, b}),
            "found,note,seed,signal.channel,signal.rms,z.theta3,z.theta4,extra\n"
            "a+b,\"x, \"\"y\"\"\",1000,force,1.5,0.5,-1.25,\n"
            ",,1001,,,,,\n");
  EXPECT_EQ(Flatten({{"x", 0.1 + 0.2}})[0].second, "0.30000000000000004");  // every digit a double needs
}

TEST(BatchEngine, ProgressCountsShardsDoneFailedAndRunningWithATimeToGo) {
  // The line the progress bar shows: 13 of 40 shards ended fill 7 of 24 places.
  EXPECT_EQ(ProgressLine({40, 12, 1, 2, 30.0, 200.0}), "[#######.................] 12/40 done, 1 failed, 2 running, 3m20s to go");
  EXPECT_EQ(ProgressLine({40, 0, 0, 2, 1.0, -1.0}), "[........................] 0/40 done, 0 failed, 2 running, time to go unknown");

  // Three shards on two threads, each an identify of a file that is no session: each fails on its
  // own (the others go on), and the progress counts them as they end.
  test::TempDir dir;
  for (const char* name : {"a.h5", "b.h5", "c.h5"}) std::ofstream(dir.file(name)) << "not a session\n";
  std::ofstream(dir.file("m.toml")) << "[[job]]\nname = \"fits\"\nkind = \"identify\"\nsessions = [\"*.h5\"]\n";
  const ResultsFolder folder = ResultsFolder::Prepare(dir.file("out"), ReadManifest(dir.file("m.toml")), false);
  std::mutex seen_lock;
  std::vector<Progress> seen;
  RunLocal(folder, AllShards(folder.plan()), 2, [&](const Progress& p) {
    std::lock_guard guard(seen_lock);
    seen.push_back(p);
  });
  ASSERT_EQ(seen.size(), 4u);  // at the start and as each shard ends
  EXPECT_EQ(seen.front().done + seen.front().failed, 0);
  EXPECT_LT(seen.front().eta, 0.0);  // nothing ended yet: unknown
  for (std::size_t k = 1; k < seen.size(); ++k) {
    EXPECT_EQ(seen[k].total, 3);
    EXPECT_EQ(seen[k].done, 0);
    EXPECT_EQ(seen[k].failed, static_cast<int>(k));
    EXPECT_LE(seen[k].running, std::min(2, 3 - static_cast<int>(k)));  // never more than the threads, nor the shards left
    EXPECT_GE(seen[k].eta, 0.0);
  }
  EXPECT_EQ(seen.back().running, 0);
  EXPECT_EQ(ProgressLine(seen.back()), "[########################] 0/3 done, 3 failed, 0 running, 0s to go");
  EXPECT_EQ(folder.Pending().size(), 3u);  // a failed shard runs again next time
  // Its record names the session once (the reader's message begins with it).
  const std::string error = folder.Record({"fits", 1})->value("error", "");
  EXPECT_EQ(error.find(dir.file("b.h5")), 0u) << error;
  EXPECT_EQ(error.find(dir.file("b.h5"), 1), std::string::npos) << error;
}

TEST(BatchSlurm, TasksFileAndScriptOfAnArray) {
  const std::vector<ShardId> shards{{"a", 0}, {"a", 2}, {"b", 1}, {"b", 3}, {"b", 4}};
  EXPECT_EQ(TasksText(shards, 2), "a/0 a/2\nb/1 b/3\nb/4\n");
  EXPECT_EQ(TasksText(shards, 1), "a/0\na/2\nb/1\nb/3\nb/4\n");
  test::TempDir dir;
  std::ofstream(dir.file("m.toml")) << "[[job]]\nname = \"a\"\nkind = \"units\"\nunits = 3\n";
  const ResultsFolder folder = ResultsFolder::Prepare(dir.file("out"), ReadManifest(dir.file("m.toml")), false);
  SlurmOptions o;
  o.partition = "short";
  o.time_limit = "0:30:00";
  const std::string script = SbatchScript(folder, folder.path() + "/slurm/array-0.tasks", 3, o, "/opt/strut it's");
  EXPECT_NE(script.find("#SBATCH --array=0-2\n"), std::string::npos) << script;
  EXPECT_NE(script.find("#SBATCH --partition=short\n"), std::string::npos);
  EXPECT_NE(script.find("#SBATCH --time=0:30:00\n"), std::string::npos);
  EXPECT_NE(script.find("exec '/opt/strut it'\\''s' batch --task-file '" + folder.path() +
                        "/slurm/array-0.tasks' --task-index \"$SLURM_ARRAY_TASK_ID\""),
            std::string::npos)
      << script;
  std::ofstream(folder.path() + "/t.tasks") << TasksText({{"a", 0}, {"a", 1}, {"a", 2}}, 2);
  const std::vector<ShardId> second = TaskShards(folder.plan(), folder.path() + "/t.tasks", 1);
  ASSERT_EQ(second.size(), 1u);
  EXPECT_EQ(second[0].shard, 2);
  EXPECT_THROW(TaskShards(folder.plan(), folder.path() + "/t.tasks", 2), BatchError);
}

}  // namespace
}  // namespace strut::batch
