// `strut identify` as a process: its JSON, exit codes, options and the files it refuses to write,
// on sessions of known truth written by the simulator (strut_test_sessions) or by `strut sim`.
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>

#include "session_fixtures.h"
#include "strut/ident/model.h"
#include "strut/ident/session_fit.h"
#include "strut_cli.h"

namespace strut::ident {
namespace {

TEST(IdentifyCommand, WritesTheFitAsJson) {
  test::TempDir dir;
  ParameterSet truth = Model::Build("2dof", Causality::kStrokeInput).defaults();
  truth.set("theta12", 0.002);  // a stroke sensor offset the fit must find
  test::WriteTwoDofSession(dir.file("s.h5"), "bhl", truth);
  const auto r = test::RunStrut("identify " + dir.file("s.h5") + " --model 2dof --input stroke --n 400 --json " +
                                dir.file("fit.json") + " --no-progress --estimate paper");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::ifstream in(dir.file("fit.json"));
  const nlohmann::json j = nlohmann::json::parse(in);
  for (const char* key : {"model", "converged", "verdict", "verdict_text", "iterations", "parameters", "channels",
                          "experiments", "loglik", "aic", "bic", "warnings"})
    EXPECT_TRUE(j.contains(key)) << key;
  EXPECT_EQ(j["model"], "2dof");
  EXPECT_TRUE(j["converged"].get<bool>());
  int estimated = 0;
  for (const auto& p : j["parameters"]) {
    for (const char* key : {"index", "name", "unit", "value", "sd", "estimated"}) EXPECT_TRUE(p.contains(key)) << key;
    estimated += p["estimated"].get<bool>();
  }
  EXPECT_EQ(estimated, 5);  // theta4, theta6, theta16 and the two offsets
  ASSERT_EQ(j["experiments"].size(), 3u);
  for (const char* key : {"mean", "sd", "rms", "noise_ratio"}) EXPECT_TRUE(j["experiments"][0]["force"].contains(key));
  for (const auto& c : j["channels"])
    for (const char* key : {"name", "variance", "noise_floor_variance", "rms", "noise_ratio"}) EXPECT_TRUE(c.contains(key)) << key;
  // The calibration the intervals hold: the lab's (the stroke, the input here, included), or what
  // --calibration names; the input's gain alone moves the estimate too.
  EXPECT_EQ(j["calibration"], (nlohmann::json{{"force", 0.002}, {"pressure", 0.002}, {"stroke", 0.001}}));
  const auto lvdt = test::RunStrut("identify " + dir.file("s.h5") + " --model 2dof --n 400 --json " +
                                   dir.file("lvdt.json") + " --no-progress --estimate paper --calibration stroke=0.1%");
  ASSERT_EQ(lvdt.exit_code, 0) << lvdt.output;
  EXPECT_NE(lvdt.output.find("gain sd stroke 0.1 %"), std::string::npos) << lvdt.output;
  std::ifstream lvdt_in(dir.file("lvdt.json"));
  const nlohmann::json k = nlohmann::json::parse(lvdt_in);
  EXPECT_EQ(k["calibration"], (nlohmann::json{{"stroke", 0.001}}));
  double largest = 0.0;  // the calibration part over the sd
  for (const auto& p : k["parameters"])
    if (p["estimated"].get<bool>()) largest = std::max(largest, p["sd_calibration"].get<double>() / p["sd"].get<double>());
  EXPECT_GT(largest, 0.1) << k["parameters"].dump();
  const auto bad = test::RunStrut("identify " + dir.file("s.h5") + " --model 2dof --estimate theta99 --no-progress");
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.output.find("theta99"), std::string::npos) << bad.output;
  // A misspelt transducer would silently leave its gain out of every interval: refused, named.
  const auto misspelt = test::RunStrut("identify " + dir.file("s.h5") + " --model 2dof --calibration forse=0.2% --no-progress");
  EXPECT_NE(misspelt.exit_code, 0);
  EXPECT_NE(misspelt.output.find("'forse' is not a channel of the model 2dof"), std::string::npos) << misspelt.output;
}

// strut identify end to end: a drawn unit's matrix and drop as two sessions, the drop fitted beside
// the matrix (its pressure channel excluded by the user), the drop and its contribution in the JSON.
TEST(IdentifyCli, FitsADropBesideTheMatrix) {
  test::TempDir dir;
  const std::string m = dir.file("m.h5"), d = dir.file("d.h5"), json = dir.file("fit.json");
  ASSERT_EQ(test::RunStrut("sim matrix --draw 1003 --seed 1003 -o " + m).exit_code, 0);
  ASSERT_EQ(test::RunStrut("sim drop --draw 1003 --seed 1003 --duration 5 --label hop -o " + d).exit_code, 0);
  const auto r = test::RunStrut("identify " + m + " " + d + " --exclude hop:pressure --no-progress --json " + json);
  EXPECT_LE(r.exit_code, 3) << r.output;  // at the noise floor or above it: either way a fit
  EXPECT_NE(r.output.find("plus the drops hop;"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("drop 'hop' adds:"), std::string::npos) << r.output;
  const nlohmann::json j = nlohmann::json::parse(test::ReadFile(json));
  ASSERT_EQ(j["transient_experiments"].size(), 1u);
  EXPECT_EQ(j["transient_experiments"][0]["label"], "hop");
  EXPECT_TRUE(j["transient_experiments"][0].contains("stroke"));
  EXPECT_FALSE(j["transient_experiments"][0].contains("pressure"));
  EXPECT_EQ(j["contributions"].back()["kind"], "drop");
  bool drop_channel = false;
  for (const auto& c : j["channels"]) drop_channel = drop_channel || c["name"] == "drop:stroke";
  EXPECT_TRUE(drop_channel);
}

TEST(SessionFit, CalibrationOptionReadsPercentOrFractionAndNamesBadItems) {
  EXPECT_EQ(ParseGainSd("force=0.1%,pressure=0.002"), (std::map<std::string, double>{{"force", 0.001}, {"pressure", 0.002}}));
  EXPECT_EQ(ParseGainSd(" force = 0.1% , pressure=0.002"), ParseGainSd("force=0.1%,pressure=0.002"));
  EXPECT_TRUE(ParseGainSd("none").empty());
  for (const char* bad : {"force", "force=", "force=-1%", "force=0.1%%", "=0.1", "force=0.1,"}) {
    SCOPED_TRACE(bad);
    EXPECT_THROW(ParseGainSd(bad), std::invalid_argument);
  }
  // An empty item is refused naming the whole text, as --set does (docs/parameters.md).
  for (const char* bad : {"force=0.1%,,pressure=0.2%", ",force=0.1%", "force=0.1%, "}) {
    SCOPED_TRACE(bad);
    try {
      ParseGainSd(bad);
      ADD_FAILURE() << "accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(std::string("calibration: '") + bad + "' has an empty item"),
                std::string::npos)
          << e.what();
    }
  }
  test::TempDir dir;
  std::ofstream(dir.file("s.h5")) << "not read: the option is refused first";
  const auto r = test::RunStrut("identify " + dir.file("s.h5") + " --calibration force=abc");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("--calibration: calibration 'force=abc'"), std::string::npos) << r.output;
}

TEST(IdentifyCommand, ExitCodesSayWhetherTheFitReachedTheNoiseFloor) {
  test::TempDir dir;
  // 2 dof data: 2dof reaches the floor (0), 1dof does not (3).
  test::WriteTwoDofSession(dir.file("s.h5"), "bcghkl");
  const auto good = test::RunStrut("identify " + dir.file("s.h5") + " --no-progress --json " + dir.file("fit.json"));
  EXPECT_EQ(good.exit_code, 0) << good.output;
  std::ifstream in(dir.file("fit.json"));
  const nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_EQ(j["verdict"], "at-noise-floor");
  const auto poor = test::RunStrut("identify " + dir.file("s.h5") + " --model 1dof --no-progress");
  EXPECT_EQ(poor.exit_code, 3) << poor.output;
  EXPECT_NE(poor.output.find("ABOVE THE NOISE FLOOR"), std::string::npos) << poor.output;
  EXPECT_NE(poor.output.find("strut discover"), std::string::npos);
}

TEST(IdentifyCommand, AnotherSchemeWithoutNTakesTheEquidistantPaperGrid) {
  // --scheme backward2 alone must not run backward2 on the thinned grid made for central4: it is
  // the fit with --n 800, to the last digit.
  test::TempDir dir;
  test::WriteTwoDofSession(dir.file("s.h5"), "bh");
  const auto estimates = [&](const std::string& options, const std::string& name) {
    const auto run = test::RunStrut("identify " + dir.file("s.h5") + " --no-progress " + options + " --json " + dir.file(name));
    EXPECT_EQ(run.exit_code, 0) << run.output;
    std::ifstream in(dir.file(name));
    const nlohmann::json fit = nlohmann::json::parse(in);
    std::map<std::string, double> values;
    for (const auto& p : fit["parameters"]) values[p["index"].get<std::string>()] = p["value"].get<double>();
    return values;
  };
  const auto alone = estimates("--scheme backward2", "a.json");
  EXPECT_GE(alone.size(), 10u);
  EXPECT_EQ(alone, estimates("--scheme backward2 --n 800", "b.json"));
}

TEST(IdentifyCommand, OutputsNeverReplaceAnInputOrASession) {
  test::TempDir dir;
  test::WriteTwoDofSession(dir.file("a.h5"), "bh");
  test::WriteTwoDofSession(dir.file("b.h5"), "bh");
  const std::string before = test::ReadFile(dir.file("a.h5"));
  // The natural slip: --json A.h5 B.h5 (info --json is a switch, identify --json takes a file).
  const auto slip = test::RunStrut("identify --json " + dir.file("a.h5") + " " + dir.file("b.h5") + " --no-progress");
  EXPECT_EQ(slip.exit_code, 1) << slip.output;
  EXPECT_NE(slip.output.find("a.h5"), std::string::npos) << slip.output;
  EXPECT_EQ(test::ReadFile(dir.file("a.h5")), before);
  const auto same = test::RunStrut("identify " + dir.file("a.h5") + " --report " + dir.file("a.h5") + " --no-progress");
  EXPECT_EQ(same.exit_code, 1);
  EXPECT_EQ(test::ReadFile(dir.file("a.h5")), before);
  const auto missing = test::RunStrut("identify " + dir.file("a.h5") + " --json " + dir.file("no/such/dir/f.json"));
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_NE(missing.output.find("does not exist"), std::string::npos) << missing.output;
}

}  // namespace
}  // namespace strut::ident
