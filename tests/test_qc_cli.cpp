// `strut qc` as a process (docs/qc.md): plan, decide, record and list the history, on sessions of
// the QC lot's units; inputs never overwritten, every error UNDECIDED.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "lot_sessions.h"
#include "strut/qc/matrix.h"
#include "strut/rig/test_matrix.h"
#include "strut_cli.h"

namespace strut::qc {
namespace {

using study::Defect;
using study::QcMatrix;
using test::QcSession;

TEST(QcCli, PlanDecideRecordAndListTheHistory) {
  test::TempDir dir;
  const auto plan = test::RunStrut("qc plan -o " + dir.file("qc.toml") + " --write-reference " + dir.file("ref.toml"));
  ASSERT_EQ(plan.exit_code, 0) << plan.output;
  const rig::MatrixPlan read = rig::ReadMatrixFile(dir.file("qc.toml"));
  EXPECT_EQ(read.sample_rate, kQcSampleRate);
  EXPECT_EQ(read.periods, kQcPeriods);
  ASSERT_EQ(read.experiments.size(), QcMatrix().experiments.size());
  for (std::size_t i = 0; i < read.experiments.size(); ++i) {
    EXPECT_EQ(read.experiments[i].label, QcMatrix().experiments[i].label);
    EXPECT_DOUBLE_EQ(read.experiments[i].frequency, QcMatrix().experiments[i].frequency);
    EXPECT_DOUBLE_EQ(read.experiments[i].amplitude, QcMatrix().experiments[i].amplitude);
    EXPECT_DOUBLE_EQ(read.experiments[i].static_position, QcMatrix().experiments[i].static_position);
  }
  daq::WriteSession(dir.file("good.h5"), QcSession(900, Defect::kNone, 900));
  EXPECT_EQ(test::RunStrut("qc plan -o " + dir.file("good.h5")).exit_code, 1);  // never over a session
  daq::WriteSession(dir.file("bad.h5"), QcSession(901, Defect::kHighOrifice, 901));
  const std::string common = " --reference " + dir.file("ref.toml") + " --db " + dir.file("qc.db");
  const auto good = test::RunStrut("qc " + dir.file("good.h5") + common + " --json " + dir.file("good.json") +
                                   " --time 2026-11-01T08:00:00Z");
  EXPECT_EQ(good.exit_code, 0) << good.output;
  const nlohmann::json gj = nlohmann::json::parse(test::ReadFile(dir.file("good.json")));
  EXPECT_EQ(gj["verdict"], "PASS");
  EXPECT_EQ(gj["serial"], "LOT-000900");
  const auto bad = test::RunStrut("qc " + dir.file("bad.h5") + common + " --report " + dir.file("bad.html") +
                                  " --time 2026-11-02T08:00:00Z");
  EXPECT_EQ(bad.exit_code, 1) << bad.output;
  EXPECT_NE(bad.output.find("orifice damping"), std::string::npos) << bad.output;
  EXPECT_NE(test::ReadFile(dir.file("bad.html")).find("FAIL"), std::string::npos);

  const auto all = test::RunStrut("qc history --db " + dir.file("qc.db") + " --json");
  ASSERT_EQ(all.exit_code, 0) << all.output;
  const auto hist = nlohmann::json::parse(all.output.substr(all.output.find('{')));
  ASSERT_EQ(hist["decisions"].size(), 2u);
  EXPECT_EQ(hist["decisions"][1]["verdict"], "FAIL");
  EXPECT_EQ(hist["counts"]["PASS"], 1);
  const auto one = test::RunStrut("qc history --db " + dir.file("qc.db") + " --serial LOT-000900");
  EXPECT_EQ(one.exit_code, 0);
  EXPECT_NE(one.output.find("1 decisions: 1 PASS"), std::string::npos) << one.output;
  EXPECT_NE(test::RunStrut("qc history --db " + dir.file("qc.db") + " --since 2026-11-02").output.find("1 decisions"),
            std::string::npos);

  // Never overwrites an input; every error is UNDECIDED (2), never FAIL.
  const std::string before = test::ReadFile(dir.file("good.h5"));
  EXPECT_EQ(test::RunStrut("qc " + dir.file("good.h5") + " --reference " + dir.file("ref.toml") + " --json " +
                           dir.file("good.h5"))
                .exit_code,
            2);
  EXPECT_EQ(test::ReadFile(dir.file("good.h5")), before);
  const auto broken = test::RunStrut("qc " + dir.file("good.h5") + " --reference " + dir.file("qc.toml"));
  EXPECT_EQ(broken.exit_code, 2) << broken.output;
  EXPECT_NE(broken.output.find("qc.toml"), std::string::npos) << broken.output;
  {
    std::ofstream(dir.file("junk.h5")) << "not hdf5";
  }
  const auto junk = test::RunStrut("qc " + dir.file("junk.h5") + " --reference " + dir.file("ref.toml"));
  EXPECT_EQ(junk.exit_code, 2) << junk.output;
  EXPECT_NE(junk.output.find("junk.h5"), std::string::npos) << junk.output;
}

}  // namespace
}  // namespace strut::qc
