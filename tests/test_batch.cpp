// The batch library alone (docs/batch.md): shard ranges cover every item once, the plan reads back
// as written, records flatten into CSV columns, the tasks file and the sbatch script of an array.
#include <gtest/gtest.h>

#include <fstream>
#include <set>

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
