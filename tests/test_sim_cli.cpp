// strut sim and strut bench sim from the command line: sessions written, mistakes reported.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "strut/daq/session.h"
#include "strut/ident/model.h"
#include "strut/sim/recorded_truth.h"
#include "strut_cli.h"

namespace strut {
namespace {

TEST(SimCli, MatrixWritesTheStandardMatrixAsAValidSession) {
  test::TempDir dir;
  const auto r = test::RunStrut("sim matrix --seed 4 -o " + dir.file("m.h5"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("14 experiments"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("simulated s per wall s"), std::string::npos);
  const daq::Session s = daq::ReadSession(dir.file("m.h5"));
  ASSERT_EQ(s.experiments.size(), 14u);
  for (const auto& e : s.experiments) {
    EXPECT_EQ(e.status, "complete") << e.label;
    EXPECT_EQ(e.periods, 3) << e.label;
    EXPECT_EQ(e.channel("pressure").reference, "gauge");
  }
  EXPECT_EQ(s.experiment("a").sample_count(), 15000u);  // 3 periods of 25 s at 200 Hz
}

TEST(SimCli, MatrixFileAndTruthFileAreUsed) {
  test::TempDir dir;
  std::ofstream(dir.file("m.toml")) << "periods = 2\nsample_rate = 400.0\n[[experiment]]\nlabel = \"x1\"\n"
                                       "frequency = 1.0\nstatic_position = 0.1\namplitude = 0.02\n";
  std::ofstream(dir.file("t.toml")) << "[effects]\nheat-exchange = true\n[actuator]\nideal = true\n";
  const auto r = test::RunStrut("sim matrix --truth " + dir.file("t.toml") + " --matrix " + dir.file("m.toml") +
                                " -o " + dir.file("x.h5"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("1dof+heat-exchange"), std::string::npos) << r.output;
  const daq::Session s = daq::ReadSession(dir.file("x.h5"));
  ASSERT_EQ(s.experiments.size(), 1u);
  EXPECT_EQ(s.experiments[0].label, "x1");
  EXPECT_EQ(s.experiments[0].sample_count(), 800u);
}

TEST(SimCli, AnExistingSessionIsReplacedOnlyWithForceAndAMissingFolderFailsBeforeTheWork) {
  test::TempDir dir;
  std::ofstream(dir.file("m.toml")) << "periods = 2\nsample_rate = 400.0\n[[experiment]]\nlabel = \"x1\"\n"
                                       "frequency = 2.0\nstatic_position = 0.1\namplitude = 0.01\n";
  const std::string run = "sim matrix --matrix " + dir.file("m.toml") + " -o " + dir.file("x.h5");
  ASSERT_EQ(test::RunStrut(run).exit_code, 0);
  const std::string before = test::ReadFile(dir.file("x.h5"));
  const auto again = test::RunStrut(run + " --seed 2");
  EXPECT_EQ(again.exit_code, 1);
  EXPECT_NE(again.output.find("--force"), std::string::npos) << again.output;
  EXPECT_EQ(test::ReadFile(dir.file("x.h5")), before);
  EXPECT_EQ(test::RunStrut(run + " --seed 2 --force").exit_code, 0);
  EXPECT_NE(test::ReadFile(dir.file("x.h5")), before);
  // The folder is checked before the simulation: the error comes at once and names it.
  const auto missing = test::RunStrut("sim matrix -o " + dir.file("no/such/x.h5"));
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_NE(missing.output.find("does not exist"), std::string::npos) << missing.output;
  EXPECT_EQ(missing.output.find("simulated rig:"), std::string::npos) << "the simulation ran first";
  // The truth file itself is never an output.
  std::ofstream(dir.file("t.toml")) << "[actuator]\nideal = true\n";
  EXPECT_EQ(test::RunStrut("sim matrix --truth " + dir.file("t.toml") + " -o " + dir.file("t.toml")).exit_code, 1);
  EXPECT_EQ(test::ReadFile(dir.file("t.toml")), "[actuator]\nideal = true\n");
}

TEST(SimCli, DropWritesADropSessionAndTheCoolingTimeConstant) {
  test::TempDir dir;
  const auto r = test::RunStrut("sim drop --mass 350 --velocity 0.5 --duration 30 -o " + dir.file("d.h5"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("time constant"), std::string::npos) << r.output;
  const daq::Session s = daq::ReadSession(dir.file("d.h5"));
  ASSERT_EQ(s.experiments.size(), 1u);
  EXPECT_EQ(s.experiments[0].kind, daq::ExperimentKind::kDrop);
  EXPECT_EQ(s.experiments[0].sample_count(), 30001u);
}

TEST(SimCli, MistakesInTheTruthFileAreReportedWithFileAndLine) {
  test::TempDir dir;
  const std::string bad = dir.file("bad.toml");
  std::ofstream(bad) << "[effects]\nheat-exchange = true\nwarp-drive = true\n";
  auto r = test::RunStrut("sim matrix --truth " + bad + " -o " + dir.file("x.h5"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find(bad + ":3"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("warp-drive"), std::string::npos);
  std::ofstream(bad) << "[parameters]\ngas_area = \"big\"\n";
  r = test::RunStrut("sim drop --truth " + bad + " -o " + dir.file("x.h5"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find(bad + ":2"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("expected a number"), std::string::npos) << r.output;
}

TEST(SimCli, TruthShowsTheModelAndWritesTheDefault) {
  test::TempDir dir;
  auto r = test::RunStrut("sim truth");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("2dof+viscous-damping+stribeck-friction+end-stop+oil-compressibility+real-gas"),
            std::string::npos);
  EXPECT_NE(r.output.find("theta30"), std::string::npos);
  r = test::RunStrut("sim truth --write-default " + dir.file("t.toml"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = test::RunStrut("sim truth --truth " + dir.file("t.toml"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
}

TEST(SimCli, BenchReportsSimulatedSecondsPerWallSecond) {
  test::TempDir dir;
  const auto r = test::RunStrut("bench sim --json " + dir.file("b.json"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("simulated s per wall s"), std::string::npos) << r.output;
  std::ifstream in(dir.file("b.json"));
  const auto j = nlohmann::json::parse(in);
  EXPECT_GT(j["matrix"]["simulated_s"].get<double>(), 300.0);
  EXPECT_GT(j["matrix"]["simulated_per_wall"].get<double>(), 0.0);
  EXPECT_EQ(j["matrix"]["experiments"].size(), 14u);
  EXPECT_GT(j["drop"]["time_constant_fit_s"].get<double>(), 10.0);
}

TEST(SimDraw, CliMatrixWithDrawRecordsATruthThatDiffersFromTheDefaults) {
  test::TempDir dir;
  std::ofstream(dir.file("m.toml")) << "periods = 1\n[[experiment]]\nlabel = \"j\"\n"
                                       "frequency = 2.0\nstatic_position = 0.133\namplitude = 0.01\n";
  const auto r = test::RunStrut("sim matrix --draw 7 --effect viscous-damping=200 --matrix " + dir.file("m.toml") +
                                " -o " + dir.file("d.h5"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto truth = sim::ReadRecordedTruth(daq::ReadSession(dir.file("d.h5")));
  ASSERT_TRUE(truth);
  ASSERT_TRUE(truth->drawn);
  EXPECT_EQ(truth->drawn->seed, 7u);
  EXPECT_EQ(truth->composition, "2dof+viscous-damping");
  EXPECT_EQ(truth->parameters.get("viscous_damping"), 200.0);
  const ident::ParameterSet defaults =
      ident::Model::Build(truth->composition, ident::Causality::kStrokeInput).defaults();
  for (const char* name : {"moving_mass", "gas_area", "volume_per_stroke", "pressure_per_temperature", "friction_base"})
    EXPECT_NE(truth->parameters.get(name), defaults.get(name)) << name;

  const auto shown = test::RunStrut("sim truth --draw 7 --base 1dof");
  ASSERT_EQ(shown.exit_code, 0) << shown.output;
  EXPECT_NE(shown.output.find("drawn: seed 7, base 1dof"), std::string::npos) << shown.output;
  const auto refused = test::RunStrut("sim truth --effect end-stop");
  EXPECT_NE(refused.exit_code, 0);
  EXPECT_NE(refused.output.find("need --draw"), std::string::npos) << refused.output;
}

}  // namespace
}  // namespace strut
