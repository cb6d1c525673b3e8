// strut demo as a user hits it: it never replaces an earlier run's session. (The full run takes
// about a minute and is what scripts/demo.sh shows; docs/demo.md.)
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "strut_cli.h"

namespace strut {
namespace {

TEST(DemoCli, AnOutFolderThatHoldsFilesIsRefusedWithoutForce) {
  test::TempDir dir;
  const std::string folder = dir.file("earlier");
  std::filesystem::create_directories(folder);
  { std::ofstream(folder + "/session.h5") << "an earlier demo's session"; }
  const auto r = test::RunStrut("demo --out " + folder);
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("--out " + folder + ": the folder is not empty"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("--force"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("demo step"), std::string::npos) << r.output;  // refused before any work
  EXPECT_EQ(test::ReadFile(folder + "/session.h5"), "an earlier demo's session");
}

TEST(DemoCli, AnOutPathThatIsAFileIsRefused) {
  test::TempDir dir;
  { std::ofstream(dir.file("f")) << "x"; }
  const auto r = test::RunStrut("demo --out " + dir.file("f"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("is not a folder"), std::string::npos) << r.output;
  EXPECT_EQ(test::ReadFile(dir.file("f")), "x");
}

}  // namespace
}  // namespace strut
