// `strut bench units --compare`: study::CompareUnits on runs written here as the bench's JSON, one
// copy with a single estimate (or z) moved by a known relative amount: the comparison must name
// that parameter, that unit and that amount, and find an unmoved copy the same.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "strut/study/units_compare.h"
#include "test_support.h"

namespace strut::study {
namespace {

// A fresh directory of this test's files (test::TempDir), removed at the end.
struct Folder {
  test::TempDir dir;
  std::filesystem::path path{dir.path()};
  std::string Write(const std::string& name, const nlohmann::json& j) const {
    const std::string file = (path / name).string();
    std::ofstream(file) << j.dump(1) << "\n";
    return file;
  }
};

// Three units as `strut bench units --json` writes them (the summary fields the comparison does
// not read included), with or without their estimates.
nlohmann::json RunJson(bool estimates = true) {
  nlohmann::json units = nlohmann::json::array();
  for (int u = 0; u < 3; ++u) {
    nlohmann::json row{{"seed", 1000 + u}, {"verdict", "at-noise-floor"}, {"worst_noise_ratio", 1.01}};
    row["z"] = {{"theta1", -1.0122 + 0.1 * u}, {"theta4", 0.0022 * (u + 1)}};
    if (estimates) row["estimate"] = {{"theta1", 1450.25 + u}, {"theta4", 0.8325 - 0.01 * u}, {"theta15", 1e-3}};
    units.push_back(row);
  }
  return {{"units", units}, {"converged", 3}, {"pooled_inside", 6}, {"pooled_total", 6}};
}

const ParameterDifference& Parameter(const UnitsComparison& c, const std::string& key) {
  for (const ParameterDifference& p : c.parameters)
    if (p.key == key) return p;
  throw std::out_of_range(key);
}

TEST(UnitsCompare, AnUnmovedCopyIsTheSame) {
  const Folder dir;
  const UnitsRun a = ReadUnitsRun(dir.Write("a.json", RunJson())), b = ReadUnitsRun(dir.Write("b.json", RunJson()));
  const UnitsComparison c = CompareUnits(a, b, 1e-9);
  EXPECT_TRUE(c.same());
  EXPECT_EQ(c.units, 3);
  EXPECT_TRUE(c.before_has_estimates);
  EXPECT_EQ(c.exceeded, 0);
  ASSERT_EQ(c.parameters.size(), 3u);  // theta1, theta15 (estimate only: the truth has no z), theta4
  for (const ParameterDifference& p : c.parameters) {
    EXPECT_EQ(p.z, 0.0) << p.key;
    EXPECT_EQ(p.estimate, 0.0) << p.key;
    EXPECT_EQ(p.estimate_units, 3) << p.key;
  }
  EXPECT_EQ(Parameter(c, "theta15").units, 0);
  EXPECT_EQ(Parameter(c, "theta1").units, 3);
}

TEST(UnitsCompare, OneMovedEstimateIsNamedWithItsUnitAndSize) {
  const Folder dir;
  nlohmann::json moved = RunJson();
  const double before = moved["units"][1]["estimate"]["theta4"].get<double>();
  moved["units"][1]["estimate"]["theta4"] = before * (1 + 3e-7);
  const UnitsRun a = ReadUnitsRun(dir.Write("a.json", RunJson())), b = ReadUnitsRun(dir.Write("moved.json", moved));
  const UnitsComparison c = CompareUnits(a, b, 1e-9);
  EXPECT_FALSE(c.same());
  EXPECT_EQ(c.exceeded, 1);
  const ParameterDifference& p = Parameter(c, "theta4");
  EXPECT_EQ(p.estimate_seed, 1001u);
  EXPECT_NEAR(p.estimate, 3e-7 / (1 + 3e-7), 1e-15);  // relative to the larger of the two
  EXPECT_EQ(p.z, 0.0);
  EXPECT_EQ(Parameter(c, "theta1").estimate, 0.0);
  // Within a tolerance above the move, the same; the comparison is symmetric.
  EXPECT_TRUE(CompareUnits(a, b, 1e-6).same());
  EXPECT_EQ(CompareUnits(b, a, 1e-9).exceeded, 1);
}

TEST(UnitsCompare, AMovedZIsFlaggedAndARunWithoutEstimatesIsComparedByZ) {
  const Folder dir;
  nlohmann::json moved = RunJson();
  moved["units"][2]["z"]["theta1"] = moved["units"][2]["z"]["theta1"].get<double>() + 1e-6;
  // The earlier run written before the estimates were kept (the baseline's format).
  const UnitsRun old = ReadUnitsRun(dir.Write("old.json", RunJson(false)));
  const UnitsComparison same = CompareUnits(old, ReadUnitsRun(dir.Write("now.json", RunJson())), 1e-9);
  EXPECT_TRUE(same.same());
  EXPECT_FALSE(same.before_has_estimates);
  EXPECT_EQ(Parameter(same, "theta1").estimate_units, 0);
  const UnitsComparison c = CompareUnits(old, ReadUnitsRun(dir.Write("moved.json", moved)), 1e-9);
  EXPECT_FALSE(c.same());
  EXPECT_EQ(c.exceeded, 1);
  EXPECT_EQ(Parameter(c, "theta1").z_seed, 1002u);
  EXPECT_GT(Parameter(c, "theta1").z, 1e-7);
}

TEST(UnitsCompare, ADroppedParameterIsADifferenceAndOtherSeedsAreNotCompared) {
  const Folder dir;
  nlohmann::json fewer = RunJson();
  fewer["units"][0]["z"].erase("theta4");
  fewer["units"][0]["estimate"].erase("theta4");
  fewer["units"][2]["seed"] = 2000;
  const UnitsComparison c =
      CompareUnits(ReadUnitsRun(dir.Write("a.json", RunJson())), ReadUnitsRun(dir.Write("b.json", fewer)), 1e-9);
  EXPECT_FALSE(c.same());
  EXPECT_EQ(c.exceeded, 0);
  EXPECT_EQ(c.units, 2);
  EXPECT_EQ(c.only_before, std::vector<unsigned long>{1002});
  EXPECT_EQ(c.only_now, std::vector<unsigned long>{2000});
  ASSERT_EQ(c.missing.size(), 2u);
  EXPECT_EQ(c.missing[0], "unit 1000: theta4's z only in the earlier run");
  EXPECT_EQ(c.missing[1], "unit 1000: theta4's estimate only in the earlier run");
  // No unit in common: nothing shows the runs agree.
  nlohmann::json other = RunJson();
  for (auto& u : other["units"]) u["seed"] = u["seed"].get<int>() + 100;
  EXPECT_FALSE(CompareUnits(ReadUnitsRun(dir.Write("a.json", RunJson())), ReadUnitsRun(dir.Write("c.json", other)), 1e-9)
                   .same());
}

TEST(UnitsCompare, RelativeDifferenceOfZeroNanAndInfinity) {
  EXPECT_EQ(RelativeDifference(0.0, 0.0), 0.0);
  EXPECT_EQ(RelativeDifference(0.0, 1e-300), 1.0);
  EXPECT_DOUBLE_EQ(RelativeDifference(-2.0, 2.0), 2.0);
  EXPECT_EQ(RelativeDifference(NAN, NAN), 0.0);
  EXPECT_TRUE(std::isinf(RelativeDifference(NAN, 1.0)));
  EXPECT_TRUE(std::isinf(RelativeDifference(INFINITY, 1.0)));
}

TEST(UnitsCompare, AFileThatIsNoRunIsRefusedByName) {
  const Folder dir;
  const std::string text = (dir.path / "text.json").string();
  std::ofstream(text) << "not json";
  const auto message = [](const std::string& path) {
    return test::ErrorOf<std::invalid_argument>([&] { ReadUnitsRun(path); });
  };
  EXPECT_NE(message(text).find(text + ": not JSON"), std::string::npos) << message(text);
  const std::string no_units = dir.Write("coverage.json", {{"coverage", {}}});
  EXPECT_NE(message(no_units).find(no_units + ": no \"units\" array"), std::string::npos) << message(no_units);
  nlohmann::json bad = RunJson();
  bad["units"][1]["z"]["theta1"] = "high";
  const std::string bad_z = dir.Write("bad.json", bad);
  EXPECT_EQ(message(bad_z), bad_z + ": units[1].z.theta1 is not a number");
  EXPECT_NE(message((dir.path / "none.json").string()).find("cannot be read"), std::string::npos);
}

}  // namespace
}  // namespace strut::study
