// `strut batch --slurm` on a real single-node Slurm (slurmctld, slurmd and munged from Debian's
// slurm-wlm and munge, started by tests/support/servers/slurm-node.sh in a temporary folder): a
// study as a job array gives the local run's merged table bit for bit; a cancelled task's shard is
// named missing by --collect, and the same command again runs that shard alone.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <fstream>
#include <regex>
#include <thread>

#include "servers.h"
#include "strut_cli.h"

namespace strut::batch {
namespace {

class SlurmNode : public ::testing::Test {
 protected:
  void SetUp() override {
    const test::ShellResult r = test::Shell(std::string(test::kServersDir) + "/slurm-node.sh start " + dir_.file("slurm"),
                                            dir_.file("start"));
    started_ = true;
    if (r.exit_code != 0) {
      reason_ = "a single-node Slurm could not start: " + r.out + r.err;
      return;
    }
    setenv("SLURM_CONF", dir_.file("slurm/slurm.conf").c_str(), 1);
  }
  void TearDown() override {
    if (started_) test::Shell(std::string(test::kServersDir) + "/slurm-node.sh stop " + dir_.file("slurm"), dir_.file("stop"));
    unsetenv("SLURM_CONF");
  }
  //! Until Slurm has no job left (the array ended or was cancelled), at most `seconds`.
  bool QueueEmpty(int seconds) {
    for (int i = 0; i < seconds * 5; ++i) {
      const test::ShellResult q = test::Shell("squeue -h", dir_.file("squeue"));
      if (q.exit_code == 0 && q.out.empty()) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
    return false;
  }
  test::TempDir dir_;
  bool started_ = false;
  std::string reason_;
};

TEST_F(SlurmNode, StudyAsAJobArrayEqualsTheLocalRunAndCollectNamesACancelledShard) {
  if (!reason_.empty()) STRUT_SERVER_UNAVAILABLE(reason_);
  std::ofstream(dir_.file("study.toml")) << "[[job]]\nname = \"units\"\nkind = \"units\"\nunits = 4\nper_shard = 1\n";
  const auto local = test::RunStrut("batch " + dir_.file("study.toml") + " --out " + dir_.file("local"));
  ASSERT_EQ(local.exit_code, 0) << local.output;

  const auto submit = test::RunStrut("batch " + dir_.file("study.toml") + " --out " + dir_.file("array") +
                                     " --slurm --partition test --time-limit 10 --no-wait");
  ASSERT_EQ(submit.exit_code, 0) << submit.output;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(submit.output, m, std::regex("submitted Slurm job (\\d+): 4 array tasks"))) << submit.output;
  const std::string job = m[1];
  // The node runs two tasks at a time: the last one is still waiting, and is killed there.
  ASSERT_EQ(test::Shell("scancel " + job + "_3", dir_.file("scancel")).exit_code, 0);
  ASSERT_TRUE(QueueEmpty(120)) << test::Shell("squeue", dir_.file("squeue")).out;
  const auto collect = test::RunStrut("batch --collect " + dir_.file("array"));
  EXPECT_EQ(collect.exit_code, 7) << collect.output;
  EXPECT_NE(collect.output.find("shard units/3 is missing"), std::string::npos) << collect.output;
  EXPECT_NE(collect.output.find("3 of 4 shards done"), std::string::npos) << collect.output;
  EXPECT_NE(collect.output.find("INCOMPLETE: 3 of 4 units"), std::string::npos) << collect.output;

  // The same command again: the missing shard alone, waited for; then the local run's table.
  const auto resume = test::RunStrut("batch " + dir_.file("study.toml") + " --out " + dir_.file("array") +
                                     " --slurm --poll 0.5");
  ASSERT_EQ(resume.exit_code, 0) << resume.output;
  EXPECT_NE(resume.output.find("4 shards, 1 to run"), std::string::npos) << resume.output;
  EXPECT_NE(resume.output.find("1 array tasks"), std::string::npos) << resume.output;
  EXPECT_EQ(test::ReadFile(dir_.file("array/units.csv")), test::ReadFile(dir_.file("local/units.csv")));
  EXPECT_EQ(test::ReadFile(dir_.file("array/results.json")), test::ReadFile(dir_.file("local/results.json")));
  EXPECT_GT(test::ReadFile(dir_.file("local/units.csv")).size(), 1000u);
}

}  // namespace
}  // namespace strut::batch
