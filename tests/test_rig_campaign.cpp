// What a matrix run settles before the rig moves (rig/campaign.h) and the matrix files it reads
// (rig/test_matrix.h): the start refused or allowed by what is at the output, the experiments a
// resume has left from a journal's session (a session built here, no file), the sample rate,
// and the matrix refused against the limits with every violation.
#include <gtest/gtest.h>

#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "strut/daq/session.h"
#include "strut/rig/campaign.h"
#include "strut/rig/test_matrix.h"
#include "test_support.h"

namespace strut::rig {
namespace {

std::string Refusal(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(not refused)";
}

RunStart Start(bool resume, bool force, std::string serial = "S1") {
  RunStart s;
  s.output = "/data/s.h5";
  s.resume = resume;
  s.force = force;
  s.serial = std::move(serial);
  return s;
}

OutputState Output(bool session, bool journal) {
  OutputState o;
  o.journal = "/data/s.h5.journal";
  o.session_exists = session;
  o.journal_exists = journal;
  return o;
}

TEST(RigCampaign, AStartIsRefusedOrAllowedByWhatIsAtTheOutput) {
  // A new session: fine on an empty output, or over a journal when forced.
  EXPECT_EQ(Refusal([] { CheckStart(Start(false, false), Output(false, false)); }), "(not refused)");
  EXPECT_EQ(Refusal([] { CheckStart(Start(false, true), Output(true, true)); }), "(not refused)");
  // Over an interrupted run's journal unforced: the journal is named, with the three ways on.
  const std::string over_journal = Refusal([] { CheckStart(Start(false, false), Output(false, true)); });
  EXPECT_NE(over_journal.find("-o /data/s.h5: the journal /data/s.h5.journal of an interrupted run is there"),
            std::string::npos)
      << over_journal;
  EXPECT_NE(over_journal.find("--resume it, `strut recover` it, or give --force"), std::string::npos);
  EXPECT_NE(Refusal([] { CheckStart(Start(false, false, ""), Output(false, false)); }).find("--serial"),
            std::string::npos);
  // A resume: needs the journal, takes no --force, needs no serial.
  EXPECT_EQ(Refusal([] { CheckStart(Start(true, false, ""), Output(false, true)); }), "(not refused)");
  EXPECT_NE(Refusal([] { CheckStart(Start(true, true), Output(false, true)); }).find("--resume and --force"),
            std::string::npos);
  EXPECT_EQ(Refusal([] { CheckStart(Start(true, false), Output(false, false)); }),
            "--resume: /data/s.h5 has no journal /data/s.h5.journal to go on from");
  // A completed session has its file and no journal: said so.
  EXPECT_NE(Refusal([] { CheckStart(Start(true, false), Output(true, false)); })
                .find("(the session was completed, or recorded without keeping it)"),
            std::string::npos);
}

MatrixEntry Entry(const std::string& label) { return {label, "middle", 1.0, 0.1, 0.01}; }

daq::Experiment Recorded(const std::string& label, const std::string& status, const std::string& matrix_label = "") {
  daq::Experiment e;
  e.label = label;
  e.status = status;
  if (!matrix_label.empty()) e.extra_attributes["matrix_label"] = matrix_label;
  return e;
}

TEST(RigCampaign, AResumeRunsWhatTheJournalsSessionLacksWithTheNextAttempt) {
  const std::vector<MatrixEntry> matrix{Entry("a"), Entry("b"), Entry("c"), Entry("d")};
  // A new session runs the matrix in order, first attempts.
  const std::vector<RunItem> all = ExperimentsToRun(Start(false, false), matrix, nullptr);
  ASSERT_EQ(all.size(), 4u);
  EXPECT_EQ(all[3].label(), "d");
  // The journal's session: a complete, b aborted once, c not steady (recorded, but run again).
  daq::Session so_far;
  so_far.damper_serial = "S1";
  so_far.experiments = {Recorded("a", "complete"), Recorded("b", "aborted"), Recorded("c", "not-steady")};
  const std::vector<RunItem> rest = ExperimentsToRun(Start(true, false), matrix, &so_far);
  ASSERT_EQ(rest.size(), 3u);
  EXPECT_EQ(rest[0].label(), "b-2");
  EXPECT_EQ(rest[1].label(), "c-2");
  EXPECT_EQ(rest[2].label(), "d");
  // The retry of b completed under its own label: b is done.
  so_far.experiments.push_back(Recorded("b-2", "complete", "b"));
  EXPECT_EQ(ExperimentsToRun(Start(true, false), matrix, &so_far).front().label(), "c-2");
  // Without a serial the session's is taken; another damper's is refused, naming both.
  EXPECT_EQ(ExperimentsToRun(Start(true, false, ""), matrix, &so_far).size(), 2u);
  EXPECT_EQ(Refusal([&] { ExperimentsToRun(Start(true, false, "S2"), matrix, &so_far); }),
            "--serial S2: the session /data/s.h5 is of damper S1");
  // Everything complete: nothing to run.
  so_far.experiments = {Recorded("a", "complete"), Recorded("b", "complete"), Recorded("c", "complete"),
                        Recorded("d", "complete")};
  EXPECT_TRUE(ExperimentsToRun(Start(true, false), matrix, &so_far).empty());
}

TEST(RigCampaign, TheSampleRateIsTheRequestedOneUnlessTheMatrixFileWantsAnother) {
  MatrixPlan plan = StandardMatrixPlan();
  EXPECT_DOUBLE_EQ(RunSampleRate(std::nullopt, plan), 200.0);
  EXPECT_DOUBLE_EQ(RunSampleRate(500.0, plan), 500.0);
  plan.source = "m.toml";
  plan.sample_rate = 100.0;
  EXPECT_DOUBLE_EQ(RunSampleRate(std::nullopt, plan), 100.0);
  EXPECT_DOUBLE_EQ(RunSampleRate(100.0, plan), 100.0);
  EXPECT_EQ(Refusal([&] { RunSampleRate(200.0, plan); }), "--daq-rate 200 Hz: the matrix m.toml wants sample_rate 100 Hz");
}

TEST(RigCampaign, AnUnsafeMatrixIsRefusedWithEveryViolationNamingTheMatrixAndTheLimits) {
  SafetyConfig safety;
  const std::vector<RunItem> fine{{Entry("a")}, {Entry("b")}};
  EXPECT_EQ(Refusal([&] { RefuseUnsafeMatrix(fine, safety, 200.0, {}, "standard", "defaults"); }), "(not refused)");
  // Beyond the stroke limit; and 1 Hz sampled at 10 Hz has too few samples a period (>= 16).
  MatrixEntry deep = Entry("deep");
  deep.static_position = safety.stroke.upper;
  deep.amplitude = 0.05;
  const std::vector<RunItem> bad{{Entry("a")}, {deep}};
  const std::string refused = Refusal([&] { RefuseUnsafeMatrix(bad, safety, 10.0, {}, "m.toml", "l.toml"); });
  EXPECT_EQ(refused.rfind("the matrix m.toml is refused before the rig moves (limits: l.toml):\n  ", 0), 0u) << refused;
  // One line per violation, as CheckMatrix gives them.
  std::vector<MatrixEntry> entries{Entry("a"), deep};
  const std::vector<std::string> each = CheckMatrix(entries, safety, 10.0);
  ASSERT_GE(each.size(), 3u);  // a and deep have too few samples a period, deep leaves the stroke range
  for (const std::string& line : each) EXPECT_NE(refused.find("\n  " + line), std::string::npos) << line;
}

TEST(RigCampaign, TheRunsMetadataHoldsTheLimitsInForce) {
  SafetyConfig safety;
  safety.force.upper = 12345.0;
  const daq::RecordingMetadata m = RunMetadata("S1", "the rig", "op", "standard", safety);
  EXPECT_EQ(m.damper_serial, "S1");
  EXPECT_EQ(m.rig, "the rig");
  EXPECT_EQ(m.operator_name, "op");
  EXPECT_EQ(m.matrix, "standard");
  bool found = false;
  for (const auto& [key, value] : m.limits)
    if (key == "force_max") found = value == 12345.0;
  EXPECT_TRUE(found);
}

TEST(RigMatrixFile, MatrixFilesAreReadAndCheckedWithLines) {
  const MatrixPlan plan = ParseMatrix(R"(sample_rate = 100.0
periods = 2
[[experiment]]
label = "slow"
frequency = 0.05
static_position = 0.133
amplitude = 0.05
[[experiment]]
label = "fast"
group = "middle"
frequency = 2.0
static_position = 0.133
amplitude = 0.005
)",
                                      "m.toml");
  ASSERT_EQ(plan.experiments.size(), 2u);
  EXPECT_EQ(plan.source, "m.toml");
  EXPECT_EQ(plan.experiments[1].label, "fast");
  EXPECT_EQ(plan.experiments[1].group, "middle");
  EXPECT_DOUBLE_EQ(*plan.sample_rate, 100.0);
  EXPECT_EQ(*plan.periods, 2);
  const auto error = [](const std::string& text) {
    return test::ErrorOf<MatrixFileError>([&] { ParseMatrix(text, "m.toml"); });
  };
  EXPECT_NE(error("[[experiment]]\nlabel = \"a\"\nfrequency = 1\n").find("m.toml:1"), std::string::npos);
  EXPECT_NE(error("[[experiment]]\nlabel = \"a\"\nfrequency = -1\nstatic_position = 0.1\namplitude = 0.01\n")
                .find("frequency must be positive"),
            std::string::npos);
  EXPECT_NE(error("[[experiment]]\nlabel = \"a\"\nfreq = 1\n").find("m.toml:3: [[experiment]] unknown key 'freq'"),
            std::string::npos);
  EXPECT_NE(error("sample_rate = 100\n").find("no [[experiment]]"), std::string::npos);
  EXPECT_NE(error("[[experiment]]\nlabel = \"a\"\nfrequency = 1\nstatic_position = 0.1\namplitude = 0.01\n"
                  "[[experiment]]\nlabel = \"a\"\nfrequency = 2\nstatic_position = 0.1\namplitude = 0.01\n")
                .find("m.toml:6: label 'a' appears twice"),
            std::string::npos);
  EXPECT_NE(error("periods = 1.5\n").find("m.toml:1: periods: expected an integer, got the number 1.5"), std::string::npos);
  EXPECT_NE(error("[[experiment]\n").find("m.toml:1:"), std::string::npos);
  try {
    ReadMatrixText("/nonexistent/m.toml");
    ADD_FAILURE() << "no error for a missing file";
  } catch (const MatrixFileError& e) {
    EXPECT_EQ(std::string(e.what()), "/nonexistent/m.toml: cannot open the matrix file");
  }
  EXPECT_EQ(StandardMatrixPlan().experiments.size(), 14u);
}

}  // namespace
}  // namespace strut::rig
