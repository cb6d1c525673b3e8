// `strut predict drop` as a process: a fit's JSON against a recorded drop, scaled parameters, and
// the inputs it never overwrites.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include "strut/sim/draw.h"
#include "strut/sim/simulated_rig.h"
#include "strut_cli.h"

namespace strut::sim {
namespace {

// strut predict drop end to end: a drop of the default truth on a perfectly calibrated rig, and a
// "fit" holding that truth's values (theta3 and theta4 estimated with 1 % sd).
TEST(PredictDropCli, ComparesScalesAndProtectsItsInputs) {
  test::TempDir dir;
  const Truth truth = WithIdealRig(DefaultTruth());
  const SimulatedRig rig(truth);
  DropSpec spec;
  spec.duration = 3.0;
  daq::WriteSession(dir.file("d.h5"), rig.RunDropSession(spec));
  const ident::Model model = truth.BuildModel(ident::Causality::kForceInput);
  nlohmann::json fit{{"model", model.composition()}, {"converged", true}, {"verdict", "at-noise-floor"}};
  const auto& d = model.defaults();
  for (int i = 0; i < d.size(); ++i) {
    const bool estimated = d.spec(i).index == 3 || d.spec(i).index == 4;
    fit["parameters"].push_back({{"index", d.spec(i).key()},
                                 {"value", rig.theta()[i]},
                                 {"sd", estimated ? nlohmann::json(0.01 * std::abs(rig.theta()[i])) : nlohmann::json()},
                                 {"estimated", estimated}});
  }
  fit["correlation"] = {{"parameters", {"theta3", "theta4"}}, {"matrix", {{1.0, 0.0}, {0.0, 1.0}}}};
  std::ofstream(dir.file("fit.json")) << fit.dump();

  const std::string base = "predict drop --fit " + dir.file("fit.json") + " --compare " + dir.file("d.h5");
  const auto r = test::RunStrut(base + " --scale theta3=2 --json " + dir.file("o.json") + " --report " + dir.file("o.html"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::ifstream in(dir.file("o.json"));
  const nlohmann::json j = nlohmann::json::parse(in);
  // Mass, velocity and length from the record.
  EXPECT_DOUBLE_EQ(j["mass"].get<double>(), 350.0);
  EXPECT_DOUBLE_EQ(j["duration"].get<double>(), 3.0);
  // The unscaled fit is the truth: it matches the record to the sensors' noise.
  const double measured = j["measured"]["peak_force"].get<double>(), fitted = j["fitted"]["peak_force"].get<double>();
  EXPECT_NEAR(fitted, measured, 0.005 * measured);
  EXPECT_NEAR(j["fitted"]["max_stroke"].get<double>(), j["measured"]["max_stroke"].get<double>(), 2e-4);
  // Doubling the orifice damping stiffens the impact: more force, less stroke; its sd doubles too.
  EXPECT_GT(j["predicted"]["peak_force"].get<double>(), fitted);
  EXPECT_LT(j["predicted"]["max_stroke"].get<double>(), j["fitted"]["max_stroke"].get<double>());
  EXPECT_DOUBLE_EQ(j["scale"]["theta3"].get<double>(), 2.0);
  const auto& iv = j["predicted"]["intervals"]["peak_force"];
  EXPECT_LT(iv["lower"].get<double>(), j["predicted"]["peak_force"].get<double>());
  EXPECT_GT(iv["upper"].get<double>(), j["predicted"]["peak_force"].get<double>());
  EXPECT_EQ(j["predicted"]["interval_parameters"], nlohmann::json({"theta3", "theta4"}));
  // The record's truth is the fitted model: no missing physics.
  EXPECT_TRUE(j["missing_physics"].empty());
  EXPECT_NE(test::ReadFile(dir.file("o.html")).find("Axle force, impact"), std::string::npos);

  // Never overwrite an input; errors name what is wrong.
  const std::string before = test::ReadFile(dir.file("d.h5"));
  auto bad = test::RunStrut(base + " --json " + dir.file("d.h5"));
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.output.find("--json"), std::string::npos) << bad.output;
  EXPECT_EQ(test::ReadFile(dir.file("d.h5")), before);
  bad = test::RunStrut(base + " --scale theta99=2");
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.output.find("theta99"), std::string::npos) << bad.output;
  bad = test::RunStrut("predict drop --fit " + dir.file("fit.json"));
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.output.find("--mass"), std::string::npos) << bad.output;
  bad = test::RunStrut("predict drop --fit " + dir.file("d.h5") + " --mass 350 --velocity 0.5");
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.output.find("not JSON"), std::string::npos) << bad.output;
}

}  // namespace
}  // namespace strut::sim
