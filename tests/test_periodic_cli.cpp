// strut periodic as a user hits it: inputs and parameters outside their range are refused before
// solving, a state the model cannot have (ident::PhysicalViolation) is not passed off as a solution,
// and one period is written as JSON.
#include <gtest/gtest.h>

#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <string>

#include "strut/ident/periodic.h"
#include "strut_cli.h"

namespace strut::ident {
namespace {

TEST(PeriodicCli, NegativeAmplitudeIsRefusedNamingTheOption) {
  const auto r = test::RunStrut("periodic --model 2dof --input stroke --frequency 1 --amplitude -1 --static 0.133 --n 100");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("--amplitude must be positive"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("Newton"), std::string::npos) << r.output;  // refused before solving
  const auto f = test::RunStrut("periodic --model 1dof --input force --frequency 1 --amplitude -1 --static 7000 --n 100");
  EXPECT_EQ(f.exit_code, 1) << f.output;
  EXPECT_NE(f.output.find("--amplitude"), std::string::npos) << f.output;
}

TEST(PeriodicCli, StrokeOutsideTheDamperIsRefusedBeforeSolving) {
  const auto r = test::RunStrut("periodic --model 2dof --input stroke --frequency 0.5 --amplitude 0.03 --static 0.35 --n 100");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("--static 0.35"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("0 .. 0.264 m (the damper's stroke)"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("Newton"), std::string::npos) << r.output;
  // The stroke offset shifts the range of the measured stroke.
  const auto shifted = test::RunStrut(
      "periodic --model 2dof --input stroke --frequency 0.5 --amplitude 0.03 --static 0.3 --n 100 --set theta12=0.1");
  EXPECT_EQ(shifted.exit_code, 0) << shifted.output;
  const auto low = test::RunStrut("periodic --model 2dof --input stroke --frequency 0.5 --amplitude 0.03 --static 0.02 --n 100");
  EXPECT_EQ(low.exit_code, 1) << low.output;
}

TEST(PeriodicCli, JsonOutputNeverReplacesItsParameterFileOrGoesNowhere) {
  const test::TempDir dir;
  const std::string params = dir.file("unit.txt");
  { std::ofstream(params) << "theta16 = 3\n"; }
  const auto onto_input = test::RunStrut("periodic --model 2dof --frequency 1 --amplitude 0.02 --static 0.133 --n 100 --params " +
                                         params + " --json " + params);
  EXPECT_NE(onto_input.exit_code, 0);
  EXPECT_NE(onto_input.output.find("--json"), std::string::npos) << onto_input.output;
  std::ifstream in(params);
  const std::string kept((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(kept, "theta16 = 3\n");  // the parameter file is intact
  const auto nowhere = test::RunStrut("periodic --model 2dof --frequency 1 --amplitude 0.02 --static 0.133 --n 100 --json " +
                                      dir.file("missing/state.json"));
  EXPECT_NE(nowhere.exit_code, 0);
  EXPECT_EQ(nowhere.output.find("Newton"), std::string::npos) << nowhere.output;  // refused before solving
  const auto written = test::RunStrut("periodic --model 2dof --frequency 1 --amplitude 0.02 --static 0.133 --n 100 --json " +
                                      dir.file("state.json"));
  EXPECT_EQ(written.exit_code, 0) << written.output;
  std::ifstream state(dir.file("state.json"));
  EXPECT_TRUE(state.good());
}

TEST(PeriodicCli, OtherOptionsOutsideTheirRange) {
  const auto freq = test::RunStrut("periodic --model 2dof --frequency 0 --amplitude 0.02 --static 0.133 --n 100");
  EXPECT_EQ(freq.exit_code, 1);
  EXPECT_NE(freq.output.find("--frequency: 0 is out of range; give a number > 0 Hz"), std::string::npos) << freq.output;
  const auto n = test::RunStrut("periodic --model 2dof --frequency 1 --amplitude 0.02 --static 0.133 --n 5");
  EXPECT_EQ(n.exit_code, 1);
  EXPECT_NE(n.output.find("--n must be in 8 .. 1000000"), std::string::npos) << n.output;
  const auto force = test::RunStrut("periodic --model 1dof --input force --frequency 1 --amplitude 1000 --static -5 --n 100");
  EXPECT_EQ(force.exit_code, 1);
  EXPECT_NE(force.output.find("--static must be a positive static force"), std::string::npos) << force.output;
}

TEST(PeriodicCli, ForceDrivingTheDamperPastItsStopsIsRefused) {
  // A mean force far below the gas preload: the model's stroke leaves the damper at full extension.
  const auto r = test::RunStrut("periodic --model 1dof --input force --frequency 0.2 --amplitude 14000 --static 14200 --n 200");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("no physical periodic solution: stroke -0."), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("outside the damper"), std::string::npos) << r.output;
}

TEST(PeriodicCli, NormalCallsStillSucceed) {
  const auto s = test::RunStrut("periodic --model 2dof --input stroke --frequency 0.5 --amplitude 0.034 --static 0.133 --n 200");
  EXPECT_EQ(s.exit_code, 0) << s.output;
  EXPECT_NE(s.output.find("time_s,stroke_m"), std::string::npos) << s.output;
  const auto f = test::RunStrut("periodic --model 2dof --input force --frequency 1 --amplitude 900 --static 6200 --n 200");
  EXPECT_EQ(f.exit_code, 0) << f.output;
}

PeriodicSolution NormalSolution(const Model& model, double frequency, double mean, double amplitude) {
  PeriodicSolver solver(model);
  return solver.Solve(PeriodicInput::Sine(frequency, mean, amplitude, 200), model.defaults().values());
}

TEST(PeriodicPhysicalViolation, NormalStateHasNone) {
  const Model stroke = Model::Build("2dof", Causality::kStrokeInput);
  EXPECT_EQ(PhysicalViolation(stroke, NormalSolution(stroke, 0.5, 0.133, 0.034), stroke.defaults().values()),
            std::nullopt);
  const Model force = Model::Build("2dof", Causality::kForceInput);
  EXPECT_EQ(PhysicalViolation(force, NormalSolution(force, 1.0, 6200, 900), force.defaults().values()), std::nullopt);
}

TEST(PeriodicPhysicalViolation, NegativeAbsolutePressureTemperatureAndStroke) {
  const Model model = Model::Build("2dof", Causality::kForceInput);
  const auto theta = model.defaults().values();
  const PeriodicSolution good = NormalSolution(model, 1.0, 6200, 900);
  const int pressure = 2, temperature = 3;  // channels: stroke, force, pressure, temperature
  ASSERT_EQ(good.channels[pressure], "pressure");
  ASSERT_EQ(good.channels[temperature], "temperature");

  PeriodicSolution bad = good;
  bad.outputs(pressure, 17) = -5.8e6;
  auto v = PhysicalViolation(model, bad, theta);
  ASSERT_TRUE(v.has_value());
  EXPECT_NE(v->find("absolute gas pressure -5.8e+06 Pa"), std::string::npos) << *v;

  bad = good;
  bad.outputs(temperature, 3) = -1.0;
  v = PhysicalViolation(model, bad, theta);
  ASSERT_TRUE(v.has_value());
  EXPECT_NE(v->find("gas temperature"), std::string::npos) << *v;

  bad = good;
  bad.unknowns(0, 40) = -8.9;  // the stroke the issue saw
  v = PhysicalViolation(model, bad, theta);
  ASSERT_TRUE(v.has_value());
  EXPECT_NE(v->find("-8.9"), std::string::npos) << *v;

  bad = good;
  bad.unknowns(0, 40) = 0.5;  // past full compression, and the gas volume 1 + theta6 q <= 0 there
  v = PhysicalViolation(model, bad, theta);
  ASSERT_TRUE(v.has_value());
  EXPECT_NE(v->find("1 + theta6 q"), std::string::npos) << *v;
}

TEST(ParameterRanges, CommandRefusesAValueOutsideTheRange) {
  const auto r = test::RunStrut("periodic --model 2dof --input stroke --frequency 1 --amplitude 0.02 --static 0.1 "
                                "--n 100 --set theta4=-1");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("theta4 gas_area = -1 m^2 is outside its physical range (0, inf)"), std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find("static equilibrium"), std::string::npos) << r.output;
}

TEST(PeriodicCommand, WritesOnePeriodAsJson) {
  test::TempDir dir;
  const auto r = test::RunStrut("periodic --model 2dof --input stroke --frequency 0.5 --amplitude 0.034 --static 0.133 "
                                "--n 200 --scheme central4 --set theta16=3 --json " + dir.file("p.json"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::ifstream in(dir.file("p.json"));
  const nlohmann::json j = nlohmann::json::parse(in);
  for (const char* key : {"time", "stroke", "force", "pressure", "temperature"}) {
    ASSERT_TRUE(j.contains(key)) << key;
    EXPECT_EQ(j[key].size(), 200u) << key;
  }
  EXPECT_DOUBLE_EQ(j["time"][0].get<double>(), 0.0);
  EXPECT_GT(j["newton_iterations"].get<int>(), 0);
  EXPECT_LT(j["residual_norm"].get<double>(), 1.0);
  EXPECT_NEAR(j["stroke"][50].get<double>(), 0.133 + 0.034, 1e-12);  // quarter period: the sine's crest
  bool found = false;
  for (const auto& p : j["parameters"])
    if (p["index"] == "theta16") found = p["value"].get<double>() == 3.0;
  EXPECT_TRUE(found);
  const auto bad = test::RunStrut("periodic --model 2dof+nonsense --frequency 1");
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.output.find("nonsense"), std::string::npos) << bad.output;
}

}  // namespace
}  // namespace strut::ident
