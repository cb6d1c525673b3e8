// `strut discover` as a process: the story as JSON beside its report.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "session_fixtures.h"
#include "strut_cli.h"

namespace strut::ident {
namespace {

TEST(DiscoverCommand, WritesTheStoryAsJson) {
  test::TempDir dir;
  test::WriteTwoDofSession(dir.file("s.h5"), "abgk");
  const auto r = test::RunStrut("discover " + dir.file("s.h5") + " --model 2dof --input stroke --n 400 --json " +
                                dir.file("d.json") + " --report " + dir.file("d.html"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::ifstream in(dir.file("d.json"));
  const nlohmann::json j = nlohmann::json::parse(in);
  for (const char* key : {"baseline", "mismatch", "missing", "final_model", "steps", "unexplained"})
    EXPECT_TRUE(j.contains(key)) << key;
  for (const char* key : {"model", "loglik", "bic", "noise_ratio"}) EXPECT_TRUE(j["baseline"].contains(key)) << key;
  EXPECT_TRUE(j["missing"].empty());
  EXPECT_EQ(j["final_model"], "2dof");
  EXPECT_NE(test::ReadFile(dir.file("d.html")).find("strutDrawFigures(["), std::string::npos);  // a report with plots
}

}  // namespace
}  // namespace strut::ident
