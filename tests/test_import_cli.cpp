// `strut import` as a process: the Silverbox record's MAT file with its preset, and its CSV with a
// column mapping and experiments of its own, read back as sessions (shared/data/README.md §2).
#include <gtest/gtest.h>

#include <string>

#include "silverbox_data.h"
#include "strut/daq/session.h"
#include "strut_cli.h"

namespace strut::ident {
namespace {

using test::kSilverboxCsv;
using test::kSilverboxMat;

TEST(SilverboxImport, CommandLineImportsTheMatFileWithThePreset) {
  REQUIRE_SILVERBOX_DATA();
  test::TempDir dir;
  const auto r = test::RunStrut("import mat '" + kSilverboxMat + "' --preset silverbox -o '" + dir.file("sb.h5") + "'");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("119214"), std::string::npos) << r.output;
  const daq::Session s = daq::ReadSession(dir.file("sb.h5"));
  EXPECT_EQ(s.experiments.size(), 12u);
  const auto info = test::RunStrut("info '" + dir.file("sb.h5") + "'");
  EXPECT_EQ(info.exit_code, 0) << info.output;
  // A column mapping of its own: only the input, two experiments of two periods each.
  const auto own = test::RunStrut("import csv '" + kSilverboxCsv + "' --column drive=V1:V --sample-rate 610.3515625 "
                                  "--periodic prefix=p,start=40986,period=4096,periods=2,count=2,stride=8692 -o '" +
                                  dir.file("own.h5") + "'");
  ASSERT_EQ(own.exit_code, 0) << own.output;
  const daq::Session o = daq::ReadSession(dir.file("own.h5"));
  ASSERT_EQ(o.experiments.size(), 2u);
  EXPECT_EQ(o.experiments[1].label, "p1");
  EXPECT_EQ(o.experiments[1].periods, 2);
  EXPECT_EQ(o.experiments[1].extra_attributes.at("first_sample"), std::to_string(40986 + 8692));
}

}  // namespace
}  // namespace strut::ident
