// The report's words and units (report/fit_report.h, report/discover_report.h): the composition
// note and the display units every figure and table uses.
#include <gtest/gtest.h>

#include "strut/report/discover_report.h"
#include "strut/report/fit_report.h"

namespace strut::ident {
namespace {

using namespace strut::report;

TEST(FitReport, CompositionNoteNamesTheCanonicalModelOnlyWhenItDiffers) {
  DiscoveryResult r;
  r.baseline.model = "1dof";
  r.missing = {"heat-exchange", "gas-solubility"};
  r.final_model = "2dof";
  EXPECT_NE(CompositionNote(r).find("1dof+heat-exchange+gas-solubility is the model 2dof"), std::string::npos)
      << CompositionNote(r);
  r.missing = {"heat-exchange"};
  r.final_model = "1dof+heat-exchange";
  EXPECT_EQ(CompositionNote(r), "");
  r.missing.clear();
  r.final_model = "1dof";
  EXPECT_EQ(CompositionNote(r), "");
}

TEST(FitReport, DisplayUnitsAreMillimetresKilonewtonsMegapascals) {
  EXPECT_DOUBLE_EQ(ChannelDisplayUnit("stroke").Value(0.125), 125.0);
  EXPECT_DOUBLE_EQ(ChannelDisplayUnit("force").Value(2500.0), 2.5);
  EXPECT_DOUBLE_EQ(ChannelDisplayUnit("pressure").Value(3.5e6), 3.5);
  EXPECT_DOUBLE_EQ(ChannelDisplayUnit("temperature").Value(293.15), 20.0);
  EXPECT_EQ(ChannelDisplayUnit("temperature").unit, "°C");
  EXPECT_EQ(DisplayUnitOf("m^2").unit, "m^2");  // compound units stay SI
  EXPECT_EQ(AxisLabel("y", ChannelDisplayUnit("y")), "y");
  EXPECT_EQ(AxisLabel("force", ChannelDisplayUnit("force")), "force [kN]");
}

}  // namespace
}  // namespace strut::ident
