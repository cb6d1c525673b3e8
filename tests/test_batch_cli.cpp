// `strut batch` on this machine's threads (docs/batch.md): the merged table of a sharded study is
// the bench command's own, a finished shard is never run again, a failed shard names its item and
// does not stop the others, a qc job's decisions land in the history once, and a results folder of
// other jobs is never overwritten.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>

#include "lot_sessions.h"
#include "strut/qc/history.h"
#include "strut_cli.h"

namespace strut::batch {
namespace {

namespace fs = std::filesystem;

void Write(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

//! stdout lines of a table, the "median s" column (the sixth word of a row line) left out: the
//! one figure that is a wall time.
std::vector<std::string> TableLines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("unit {", 0) == 0 || line.rfind("[", 0) == 0 || line.empty()) continue;  // unit records, logs
    std::istringstream words(line);
    std::vector<std::string> w;
    for (std::string x; words >> x;) w.push_back(x);
    if (w.size() >= 7 && (w[0] == "none" || w[0] == "viscous-damping")) w.erase(w.begin() + 5);
    std::string joined;
    for (const auto& x : w) joined += x + " ";
    out.push_back(joined);
  }
  return out;
}

nlohmann::json WithoutSeconds(nlohmann::json j) {
  j.erase("seconds");
  j.erase("index");
  j.erase("timing");
  return j;
}

TEST(BatchCli, ShardedStudyMergesIntoTheBenchCommandsTableAndResumes) {
  test::TempDir dir;
  Write(dir.file("study.toml"), R"([[job]]
name = "conf"
kind = "confusion"
units = 2
first_seed = 2000
effects = ["none", "viscous-damping"]
per_shard = 1
)");
  const auto bench = test::RunStrut("bench confusion --units 2 --first-seed 2000 --effects none,viscous-damping --json " +
                                    dir.file("bench.json") + " 2>/dev/null");
  ASSERT_EQ(bench.exit_code, 0) << bench.output;
  const auto run = test::RunStrut("batch " + dir.file("study.toml") + " --out " + dir.file("out") + " --threads 2");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("4 shards, 4 to run"), std::string::npos) << run.output;
  // The table: the bench command's, line by line, but for the wall times.
  EXPECT_EQ(TableLines(test::ReadFile(dir.file("out/conf.txt"))), TableLines(bench.output));
  // Every unit's record: the bench command's.
  const nlohmann::json b = nlohmann::json::parse(test::ReadFile(dir.file("bench.json")));
  const nlohmann::json r = nlohmann::json::parse(test::ReadFile(dir.file("out/results.json")));
  ASSERT_EQ(r["jobs"][0]["results"].size(), 4u);
  for (int k = 0; k < 4; ++k) {
    EXPECT_EQ(r["jobs"][0]["results"][k]["index"], k);
    EXPECT_EQ(WithoutSeconds(r["jobs"][0]["results"][k]), WithoutSeconds(b["units"][k])) << k;
  }
  const std::string csv = test::ReadFile(dir.file("out/conf.csv"));
  EXPECT_EQ(test::Count(csv, "\n"), 5u) << csv;  // a heading and four units
  EXPECT_EQ(csv.find("seconds"), std::string::npos) << "a wall time in the merged table: " << csv;

  // A killed batch: one shard's record lost. Run again: that shard alone runs, the others stay.
  const std::string kept = test::ReadFile(dir.file("out/shards/conf.00001.json"));
  fs::remove(dir.file("out/shards/conf.00002.json"));
  const auto again = test::RunStrut("batch " + dir.file("study.toml") + " --out " + dir.file("out"));
  ASSERT_EQ(again.exit_code, 0) << again.output;
  EXPECT_NE(again.output.find("4 shards, 1 to run"), std::string::npos) << again.output;
  EXPECT_EQ(test::ReadFile(dir.file("out/shards/conf.00001.json")), kept);
  EXPECT_EQ(nlohmann::json::parse(test::ReadFile(dir.file("out/results.json"))), r);
  const auto nothing = test::RunStrut("batch " + dir.file("study.toml") + " --out " + dir.file("out"));
  EXPECT_NE(nothing.output.find("0 to run"), std::string::npos) << nothing.output;

  // Other jobs in the same folder: refused without --force; a folder of other files: refused.
  Write(dir.file("other.toml"), "[[job]]\nkind = \"units\"\nunits = 1\n");
  const auto other = test::RunStrut("batch " + dir.file("other.toml") + " --out " + dir.file("out"));
  EXPECT_EQ(other.exit_code, 1);
  EXPECT_NE(other.output.find("holds the results of other jobs"), std::string::npos) << other.output;
  EXPECT_TRUE(fs::exists(dir.file("out/shards/conf.00001.json")));
  fs::create_directory(dir.file("mine"));
  Write(dir.file("mine/notes.txt"), "keep me");
  const auto mine = test::RunStrut("batch " + dir.file("other.toml") + " --out " + dir.file("mine") + " --force");
  EXPECT_EQ(mine.exit_code, 1);
  EXPECT_EQ(test::ReadFile(dir.file("mine/notes.txt")), "keep me");
}

//! The lines of a bench qc table that hold no time (the unit lines, the time and the load lines do).
std::string LotFigures(const std::string& text) {
  std::string out;
  std::istringstream in(text);
  bool table = false;
  for (std::string line; std::getline(in, line);) {
    table = table || line.rfind("confusion matrix", 0) == 0;
    if (table && line.rfind("decision time", 0) != 0 && !line.empty() && line[0] != '[') out += line + "\n";
  }
  return out;
}

TEST(BatchCli, QcLotStudyInShardsIsTheBenchCommandsLot) {
  test::TempDir dir;
  Write(dir.file("lot.toml"), "[[job]]\nname = \"lot\"\nkind = \"qc-lot\"\nunits = 5\nper_shard = 2\n");
  const auto bench = test::RunStrut("bench qc --units 5 2>/dev/null");
  ASSERT_EQ(bench.exit_code, 0) << bench.output;
  const auto run = test::RunStrut("batch " + dir.file("lot.toml") + " --threads 2");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const std::string figures = LotFigures(test::ReadFile(dir.file("lot.batch/lot.txt")));
  EXPECT_NE(figures.find("under-charge         0     1"), std::string::npos) << figures;
  EXPECT_EQ(figures, LotFigures(bench.output));
}

TEST(BatchCli, DropStudyInShardsIsTheBenchCommandsDropStudy) {
  test::TempDir dir;
  Write(dir.file("drop.toml"), "[[job]]\nname = \"drop\"\nkind = \"drop\"\nunits = 2\nduration = 10\n");
  const auto bench = test::RunStrut("bench drop --units 2 --duration 10 2>/dev/null");
  ASSERT_EQ(bench.exit_code, 0) << bench.output;
  const auto run = test::RunStrut("batch " + dir.file("drop.toml") + " --threads 2 2>/dev/null");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const auto no_times = [](const std::string& text) {  // every "N ms": the predictions' times among them
    return std::regex_replace(std::regex_replace(text, std::regex("\\d+ ms"), "ms"), std::regex("\n+$"), "");
  };
  EXPECT_NE(bench.output.find("peak force"), std::string::npos) << bench.output;
  EXPECT_EQ(no_times(test::ReadFile(dir.file("drop.batch/drop.txt"))), no_times(bench.output));
}

TEST(BatchCli, QcJobRecordsEachDecisionOnceAndAFailedShardNamesItsSession) {
  test::TempDir dir;
  ASSERT_EQ(test::RunStrut("qc plan --write-reference " + dir.file("ref.toml") + " >/dev/null").exit_code, 0);
  fs::create_directory(dir.file("archive"));
  daq::WriteSession(dir.file("archive/a.h5"), test::QcSession(900, study::Defect::kNone, 900));
  daq::WriteSession(dir.file("archive/b.h5"), test::QcSession(901, study::Defect::kHighOrifice, 901));
  Write(dir.file("archive/c.h5"), "not a session");
  Write(dir.file("night.toml"), R"([[job]]
name = "recheck"
kind = "qc"
sessions = ["archive/a.h5", "archive/b.h5"]
reference = "ref.toml"
db = "qc.db"

[[job]]
name = "fits"
kind = "identify"
sessions = ["archive/*.h5"]
model = "2dof+viscous-damping"
)");
  const auto run = test::RunStrut("batch " + dir.file("night.toml") + " --out " + dir.file("out"));
  EXPECT_EQ(run.exit_code, 7) << run.output;  // one shard failed
  EXPECT_NE(run.output.find("shard fits/2 failed: " + fs::canonical(dir.path()).string() + "/archive/c.h5"),
            std::string::npos)
      << run.output;
  EXPECT_NE(run.output.find("1 PASS"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("1 FAIL"), std::string::npos) << run.output;
  const nlohmann::json r = nlohmann::json::parse(test::ReadFile(dir.file("out/results.json")));
  EXPECT_EQ(r["jobs"][1]["results"].size(), 2u);  // the two good sessions' fits
  EXPECT_FALSE(r["jobs"][1]["complete"]);
  {
    const qc::History h(dir.file("qc.db"));
    const auto entries = h.Query();
    ASSERT_EQ(entries.size(), 2u);
    EXPECT_EQ(entries[0].key.rfind("batch:", 0), 0u) << entries[0].key;
  }
  // Run again (the failed shard again, and the qc shards' records lost): no decision twice.
  fs::remove(dir.file("out/shards/recheck.00000.json"));
  fs::remove(dir.file("out/shards/recheck.00001.json"));
  const auto again = test::RunStrut("batch " + dir.file("night.toml") + " --out " + dir.file("out"));
  EXPECT_EQ(again.exit_code, 7) << again.output;
  EXPECT_NE(again.output.find("3 to run"), std::string::npos) << again.output;
  EXPECT_EQ(qc::History(dir.file("qc.db")).Query().size(), 2u);
  const auto collected = test::RunStrut("batch --collect " + dir.file("out"));
  EXPECT_EQ(collected.exit_code, 7);
  EXPECT_NE(collected.output.find("shard fits/2 failed"), std::string::npos) << collected.output;
}

TEST(BatchCli, ManifestErrorsNameTheFileAndLine) {
  test::TempDir dir;
  Write(dir.file("m.toml"), "[[job]]\nkind = \"units\"\nunits = 2\n\n[[job]]\nkind = \"qc\"\nsessions = [\"none/*.h5\"]\nreference = \"r.toml\"\n");
  const auto r = test::RunStrut("batch " + dir.file("m.toml"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find(dir.file("m.toml") + ":7: sessions: 'none/*.h5' matches no file"), std::string::npos)
      << r.output;
  Write(dir.file("n.toml"), "[[job]]\nkind = \"units\"\nunit = 2\n");
  const auto n = test::RunStrut("batch " + dir.file("n.toml"));
  EXPECT_NE(n.output.find(":3: [[job]] 1: unknown key 'unit'"), std::string::npos) << n.output;
  EXPECT_FALSE(fs::exists(dir.file("n.batch")));
}

}  // namespace
}  // namespace strut::batch
