// `strut info` as a process: a session file as JSON in SI units and as an aligned table, and a
// defective file (broken with the HDF5 C API) named with every defect, exit code 1.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <string>

#include "session_file_fixtures.h"
#include "strut_cli.h"

namespace {

using strut::test::ExpectMentions;
using strut::test::FileEditor;
using strut::test::TempDir;
using strut::test::WriteGoodFile;

TEST(SessionFiles, InfoJsonListsTheSessionInSiUnits) {
  TempDir dir;
  const std::string path = WriteGoodFile(dir);
  const auto result = strut::test::RunStrut("info " + path + " --json");
  ASSERT_EQ(result.exit_code, 0) << result.output;
  const nlohmann::json j = nlohmann::json::parse(result.output);
  EXPECT_EQ(j["file"], path);
  EXPECT_EQ(j["format_version"], 1);
  EXPECT_EQ(j["created_utc"], "2026-11-22T05:32:50Z");
  EXPECT_EQ(j["damper_serial"], "MLG-0042");
  EXPECT_EQ(j["rig"], "shaker-2");
  EXPECT_EQ(j["valid"], true);
  ASSERT_EQ(j["experiments"].size(), 3u);
  const nlohmann::json& a = j["experiments"][0];
  EXPECT_EQ(a["label"], "a");
  EXPECT_EQ(a["kind"], "periodic");
  EXPECT_EQ(a["status"], "complete");
  EXPECT_EQ(a["group"], "high");
  EXPECT_EQ(a["frequency"], 2.0);
  EXPECT_EQ(a["amplitude"], 0.01);
  EXPECT_EQ(a["static_position"], 0.1);
  EXPECT_EQ(a["periods"], 3);
  EXPECT_EQ(a["samples"], 300);
  EXPECT_EQ(a["sample_rate"], 200.0);
  ASSERT_EQ(a["channels"].size(), 4u);
  EXPECT_EQ(a["channels"][2]["name"], "pressure");
  EXPECT_EQ(a["channels"][2]["units"], "Pa");
  EXPECT_EQ(a["channels"][2]["reference"], "absolute");
  EXPECT_FALSE(a["channels"][0].contains("reference"));
  const nlohmann::json& b = j["experiments"][1];
  EXPECT_EQ(b["kind"], "drop");
  EXPECT_TRUE(b["frequency"].is_null());
  EXPECT_EQ(b["channels"][2]["reference"], "gauge");
}

TEST(SessionFiles, InfoPrintsAnAlignedTable) {
  TempDir dir;
  const std::string path = WriteGoodFile(dir);
  const auto result = strut::test::RunStrut("info " + path);
  ASSERT_EQ(result.exit_code, 0) << result.output;
  ExpectMentions(result.output,
                 {path, "MLG-0042", "ampl [mm]", "periodic", "pressure[Pa, absolute]",
                  "pressure[Pa, gauge]", "temperature[K]"});
}

TEST(SessionFiles, InfoOnADefectiveFileExitsWithOneAndNamesTheFile) {
  TempDir dir;
  const std::string path = WriteGoodFile(dir);
  {
    FileEditor edit(path);
    edit.RemoveAttribute("/experiments/a", "periods");
    edit.SetString("/experiments/b/stroke", "units", "mm");
  }
  const auto result = strut::test::RunStrut("info " + path);
  EXPECT_EQ(result.exit_code, 1);
  ExpectMentions(result.output, {path + ": experiment 'a': attribute 'periods': missing",
                                 path + ": experiment 'b': channel 'stroke'"});
  const auto json = strut::test::RunStrut("info " + path + " --json");
  EXPECT_EQ(json.exit_code, 1);
  const nlohmann::json j = nlohmann::json::parse(json.output);
  EXPECT_EQ(j["valid"], false);
  EXPECT_EQ(j["errors"].size(), 2u);
}

}  // namespace
