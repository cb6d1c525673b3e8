// Logs to stderr, data to stdout: what each command prints on stdout parses as its data (a table,
// CSV, JSON, a report) and holds no log line; progress and log lines are on stderr, and a
// conclusion is printed once.
#include <gtest/gtest.h>

#include <algorithm>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "session_fixtures.h"
#include "strut_cli.h"

namespace strut {
namespace {

const std::string kStrut = STRUT_BINARY;

std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

bool HasLogLine(const std::string& text) {
  for (const char* level : {"[info]", "[warning]", "[error]", "[debug]"})
    if (text.find(level) != std::string::npos) return true;
  return false;
}

// A 2 dof session of experiments b and h of the standard matrix, exactly the model (no noise model
// error), so that 2dof fits it to the noise floor.
std::string TwoDofSession(const test::TempDir& dir) {
  test::WriteTwoDofSession(dir.file("s.h5"), "bh");
  return dir.file("s.h5");
}

TEST(CliStreams, InfoJsonIsTheOnlyThingOnStdout) {
  test::TempDir dir;
  const std::string session = TwoDofSession(dir);
  const auto r = test::Shell(kStrut + " -v info --json " + session, dir.file("info"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);  // throws if anything else is there
  EXPECT_EQ(j["experiments"].size(), 2u);
  // A damaged file: the errors travel in the JSON (stdout), exit code 1.
  const auto bad =
      test::Shell(kStrut + " info --json " + std::string(STRUT_SOURCE_DIR) + "/README.md", dir.file("bad"));
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_EQ(nlohmann::json::parse(bad.out)["valid"], false);
  // The table: data on stdout, nothing on stderr.
  const auto table = test::Shell(kStrut + " info " + session, dir.file("table"));
  ASSERT_EQ(table.exit_code, 0) << table.err;
  EXPECT_NE(table.out.find("experiments    2 (file is valid)"), std::string::npos) << table.out;
  EXPECT_FALSE(HasLogLine(table.out));
}

TEST(CliStreams, PeriodicPrintsCsvOrJsonOnStdoutAndItsLogOnStderr) {
  test::TempDir dir;
  const std::string args = " periodic --model 2dof --frequency 0.5 --amplitude 0.034 --static 0.133 --n 64";
  const auto csv = test::Shell(kStrut + args, dir.file("csv"));
  ASSERT_EQ(csv.exit_code, 0) << csv.err;
  const std::vector<std::string> lines = Lines(csv.out);
  ASSERT_EQ(lines.size(), 65u) << csv.out;  // a header and one row per grid point
  const auto columns = std::count(lines[0].begin(), lines[0].end(), ',');
  for (std::size_t i = 1; i < lines.size(); ++i) {
    EXPECT_EQ(std::count(lines[i].begin(), lines[i].end(), ','), columns) << lines[i];
    std::istringstream row(lines[i]);
    for (std::string cell; std::getline(row, cell, ',');) EXPECT_NO_THROW(std::stod(cell)) << lines[i];
  }
  EXPECT_NE(csv.err.find("Newton iterations"), std::string::npos) << csv.err;
  const auto json = test::Shell(kStrut + args + " --json -", dir.file("json"));
  ASSERT_EQ(json.exit_code, 0) << json.err;
  EXPECT_EQ(nlohmann::json::parse(json.out)["n"], 64);
  EXPECT_NE(json.err.find("Newton iterations"), std::string::npos);
}

TEST(CliStreams, IdentifyPrintsItsReportOnStdoutAndLogsOnStderr) {
  test::TempDir dir;
  const std::string session = TwoDofSession(dir);
  const auto r =
      test::Shell(kStrut + " identify " + session + " --n 200 --json " + dir.file("fit.json"), dir.file("id"));
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_FALSE(HasLogLine(r.out)) << r.out;
  EXPECT_NE(r.out.find("theta4"), std::string::npos) << r.out;  // the report's parameter table
  EXPECT_NE(r.err.find("starting values as used"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("[info] wrote " + dir.file("fit.json")), std::string::npos) << r.err;
  EXPECT_EQ(r.out.find("wrote"), std::string::npos) << r.out;
}

TEST(CliStreams, DiscoverPrintsItsConclusionOnceOnStdout) {
  test::TempDir dir;
  const std::string session = TwoDofSession(dir);
  const auto r = test::Shell(kStrut + " discover " + session + " --n 200", dir.file("discover"));
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  const std::string conclusion = "explains the data to the noise floor";
  EXPECT_EQ(test::Count(r.out, conclusion), 1u) << r.out;
  EXPECT_EQ(test::Count(r.err, conclusion), 0u) << r.err;
  EXPECT_FALSE(HasLogLine(r.out)) << r.out;
  EXPECT_NE(r.err.find("[info]"), std::string::npos) << r.err;  // its progress
}

}  // namespace
}  // namespace strut
