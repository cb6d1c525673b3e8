// The discovery's JSON record (report::DiscoveryJson, `strut discover --json`) on a discovery
// written here: every step with its candidates in order, the findings as they were located, and
// null for a ratio that was not computed.
#include <gtest/gtest.h>

#include <cmath>

#include "strut/report/discover_report.h"

namespace strut::report {
namespace {

TEST(DiscoveryJson, HoldsTheStepsCandidatesAndFindingsWithNullForWhatWasNotComputed) {
  ident::DiscoveryResult r;
  r.baseline.model = "1dof";
  r.mismatch = {{"loop-frequency", "force", 41.5, "the loops widen with frequency"}};
  r.missing = {"heat-exchange"};
  r.final_model = "1dof+heat-exchange";
  ident::DiscoveryStep step;
  step.term = "heat-exchange";
  step.evidence = "loop-frequency 41.5";
  step.delta_bic = -216289.6;
  step.noise_before = {{"force", 57.0}, {"pressure", NAN}};
  step.noise_after = {{"force", 1.02}};
  step.parameters = {{"theta15", 0.8}};
  step.cv_before = 60.0;  // cv_after not computed
  ident::CandidateFit kept{"heat-exchange", true, "", -216289.6, 41.5, {{"force", 1.02}}, 1.1, "kept"};
  ident::CandidateFit failed{"end-stop", false, "no periodic solution", 0.0, 0.3, {}, NAN, "no solution"};
  step.candidates = {kept, failed};
  r.steps = {step};
  r.conclusion = "heat exchange was missing";

  const nlohmann::json j = DiscoveryJson(r);
  EXPECT_EQ(j["baseline"]["model"], "1dof");
  EXPECT_EQ(j["mismatch"][0], nlohmann::json({{"locus", "loop-frequency"}, {"channel", "force"}, {"score", 41.5},
                                              {"detail", "the loops widen with frequency"}}));
  EXPECT_EQ(j["missing"], nlohmann::json({"heat-exchange"}));
  EXPECT_EQ(j["final_model"], "1dof+heat-exchange");
  ASSERT_EQ(j["steps"].size(), 1u);
  const nlohmann::json& s = j["steps"][0];
  EXPECT_DOUBLE_EQ(s["delta_bic"].get<double>(), -216289.6);
  EXPECT_DOUBLE_EQ(s["noise_before"]["force"].get<double>(), 57.0);
  EXPECT_TRUE(s["noise_before"]["pressure"].is_null());
  EXPECT_DOUBLE_EQ(s["parameters"]["theta15"].get<double>(), 0.8);
  EXPECT_DOUBLE_EQ(s["cv_noise_ratio_before"].get<double>(), 60.0);
  ASSERT_EQ(s["candidates"].size(), 2u);
  EXPECT_EQ(s["candidates"][0]["verdict"], "kept");
  EXPECT_DOUBLE_EQ(s["candidates"][0]["cv_noise_ratio"].get<double>(), 1.1);
  EXPECT_EQ(s["candidates"][1]["term"], "end-stop");
  EXPECT_FALSE(s["candidates"][1]["ok"].get<bool>());
  EXPECT_EQ(s["candidates"][1]["error"], "no periodic solution");
  EXPECT_TRUE(s["candidates"][1]["cv_noise_ratio"].is_null());
  EXPECT_TRUE(j["unexplained"].empty());
  EXPECT_EQ(j["conclusion"], "heat exchange was missing");
  EXPECT_TRUE(j.contains("final_fit"));
  // The record is what the command writes: NaN never reaches the text.
  EXPECT_EQ(j.dump().find("NaN"), std::string::npos);
}

}  // namespace
}  // namespace strut::report
