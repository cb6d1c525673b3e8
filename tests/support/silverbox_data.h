// Where the Silverbox benchmark's measured record lies (shared/data/silverbox, outside the
// repository): its tests skip when it is not there.
#pragma once

#include <filesystem>
#include <string>

namespace strut::test {

inline const std::string kSilverboxData = std::string(STRUT_SHARED_DIR) + "/data/silverbox";
inline const std::string kSilverboxCsv = kSilverboxData + "/SNLS80mV.csv";
inline const std::string kSilverboxMat = kSilverboxData + "/SNLS80mV.mat";

inline bool HaveSilverboxData() {
  return std::filesystem::exists(kSilverboxMat) && std::filesystem::exists(kSilverboxCsv);
}

}  // namespace strut::test

#define REQUIRE_SILVERBOX_DATA() \
  if (!strut::test::HaveSilverboxData()) GTEST_SKIP() << "no Silverbox data in " << strut::test::kSilverboxData
