// Truth files: the shipped default (physically consistent, compiled in), the mapping of effects to
// model compositions, and mistakes a user can make, each reported with the file and line.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "strut/sim/simulated_rig.h"
#include "strut/sim/truth.h"
#include "test_support.h"

namespace strut::sim {
namespace {

std::string ErrorOf(const std::string& text) {
  try {
    ParseTruth(text, "bad.toml");
  } catch (const TruthError& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(SimTruth, ShippedFileIsTheBuiltInDefault) {
  const std::string shipped = test::ReadFile(
      (std::filesystem::path(STRUT_SOURCE_DIR) / "sim/data/f16-nose-lab.toml").string());  // not __FILE__: a
  // compiler cache's base directory makes that relative
  ASSERT_FALSE(shipped.empty());
  EXPECT_EQ(shipped, std::string(DefaultTruthText()));
  const Truth t = DefaultTruth();
  // Every effect of the paper's models and the simulated rig's first extras on; the later catalogue
  // terms (dead volume, recoil, metering pin, friction asymmetry, pressure-dependent heat transfer)
  // are for drawn units.
  EXPECT_EQ(t.effects, (std::vector<std::string>{"heat-exchange", "gas-solubility", "viscous-damping",
                                                 "stribeck-friction", "end-stop", "oil-compressibility", "real-gas"}));
  EXPECT_EQ(t.Composition(), "2dof+viscous-damping+stribeck-friction+end-stop+oil-compressibility+real-gas");
  EXPECT_EQ(t.damper_serial, "SIM-F16N-0001");
}

TEST(SimTruth, DefaultDamperIsPhysicallyConsistent) {
  const Truth t = DefaultTruth();
  const ident::Model model = t.BuildModel(ident::Causality::kStrokeInput);
  const ident::ParameterSet p = t.Parameters(model);
  // Charge: 0.70 MPa absolute at full extension at ambient temperature (real gas, solubility).
  const double measured_zero = p.get("stroke_offset");
  const std::vector<double> at_rest = model.StaticEquilibrium(measured_zero + 0.005, p.values());
  const std::vector<double> extended = model.StaticEquilibrium(measured_zero, p.values());
  EXPECT_NEAR(extended[1], 7.0e5, 1.5e3);  // the top-out stop holds it there
  EXPECT_NEAR(at_rest[2], 293.15, 1e-6);
  // Net gas force 3 kN at extension and 10 kN near 200 mm static (damper-physics.md §1.5); the
  // static axle force also carries the 40 kg fixture.
  const double fixture = p.get("moving_mass") * p.get("gravity");
  EXPECT_NEAR(model.StaticEquilibrium(measured_zero + 0.005, p.values())[0] - fixture, 3.05e3, 0.1e3);
  EXPECT_NEAR(model.StaticEquilibrium(measured_zero + 0.200, p.values())[0] - fixture, 10.0e3, 0.5e3);
  // Thermal time constant 10 s at extension (brief: 10-30 s), gas mass 12 g of N2.
  EXPECT_NEAR(p.get("gas_heat_capacity") / p.get("wall_heat_conductance"), 10.0, 0.05);
  const double gas_mass = p.get("pressure_per_temperature") * 1.5e-3 / 296.8;  // theta5 V0 / R_N2
  EXPECT_NEAR(gas_mass, 0.0121, 0.0002);
  EXPECT_NEAR(p.get("gas_heat_capacity") / (gas_mass * 743.0), 2.0, 0.05);  // kappa = 2
  EXPECT_NEAR(-p.get("gas_area") / p.get("volume_per_stroke"), 1.5e-3, 1e-6);  // V0
}

TEST(SimTruth, EffectsMapOntoModelCompositions) {
  Truth t;
  t.effects = {};
  EXPECT_EQ(t.Composition(), "1dof");
  t.effects = {"heat-exchange"};
  EXPECT_EQ(t.BuildModel(ident::Causality::kForceInput).composition(), "1dof+heat-exchange");
  t.effects = {"heat-exchange", "gas-solubility", "end-stop"};
  EXPECT_EQ(t.BuildModel(ident::Causality::kForceInput).composition(), "2dof+end-stop");
  t.effects = {"real-gas", "viscous-damping"};
  EXPECT_EQ(t.Composition(), "1dof+viscous-damping+real-gas");
  t.effects = {"real-gas", "oil-compressibility", "heat-exchange", "gas-solubility"};
  EXPECT_EQ(t.Composition(), t.BuildModel(ident::Causality::kForceInput).composition());

  const Truth polytropic = ParseTruth(
      "[effects]\nheat-exchange = false\nviscous-damping = true\n[parameters]\npolytropic_exponent = 1.25\n"
      "extended_pressure = 7.5e5\nwall_heat_conductance = 3.0  # off: ignored with a warning\n",
      "poly.toml");
  const ident::Model model = polytropic.BuildModel(ident::Causality::kStrokeInput);
  EXPECT_EQ(model.composition(), "1dof+viscous-damping");
  EXPECT_DOUBLE_EQ(polytropic.Parameters(model).get("theta7"), 1.25);
  EXPECT_DOUBLE_EQ(polytropic.Parameters(model).get("theta5"), 7.5e5);
}

TEST(SimTruth, MistakesNameTheFileAndLine) {
  EXPECT_NE(ErrorOf("[effects]\nheat-exchange = true\nwarp-drive = true\n").find("bad.toml:3"), std::string::npos);
  EXPECT_NE(ErrorOf("[effects]\nwarp-drive = true\n").find("unknown effect 'warp-drive'"), std::string::npos);
  EXPECT_NE(ErrorOf("[effects]\nwarp-drive = true\n").find("real-gas"), std::string::npos);  // lists the known ones
  const std::string unknown = ErrorOf("[effects]\nheat-exchange = true\n\n[parameters]\ngas_area = 5e-3\ngas_aera = 1\n");
  EXPECT_NE(unknown.find("bad.toml:6"), std::string::npos) << unknown;
  EXPECT_NE(unknown.find("unknown parameter 'gas_aera'"), std::string::npos) << unknown;
  // The load cell's zero is a sensor's: a plant force of that name would be counted twice.
  const std::string zero = ErrorOf("[parameters]\ngas_area = 5e-3\nload_cell_zero = 60\n");
  EXPECT_NE(zero.find("bad.toml:3"), std::string::npos) << zero;
  EXPECT_NE(zero.find("[sensors.force] offset"), std::string::npos) << zero;
  const std::string not_number = ErrorOf("[parameters]\ngas_area = \"five\"\n");
  EXPECT_NE(not_number.find("bad.toml:2"), std::string::npos) << not_number;
  EXPECT_NE(not_number.find("expected a number"), std::string::npos) << not_number;
  EXPECT_NE(ErrorOf("[parameters]\nmoving_mass = -4\n").find("moving_mass = -4 is outside its physical range (0, inf)"), std::string::npos);
  EXPECT_NE(ErrorOf("[parameters]\ngas_area = 5e-3 5\n").find("bad.toml:2"), std::string::npos);  // TOML syntax
  EXPECT_NE(ErrorOf("[actuater]\nideal = true\n").find("unknown table [actuater]"), std::string::npos);
  EXPECT_NE(ErrorOf("[actuator]\nbandwidth = 10\n").find("unknown key 'bandwidth'"), std::string::npos);
  EXPECT_NE(ErrorOf("[actuator]\nloop_bandwidth = 150\n").find("valve_bandwidth"), std::string::npos);
  EXPECT_NE(ErrorOf("[sensors.force]\nrange = [1, -1]\n").find("bad.toml:1"), std::string::npos);
  EXPECT_NE(ErrorOf("[effects]\ngas-solubility = true\n").find("needs heat-exchange"), std::string::npos);
  EXPECT_NE(ErrorOf("[[faults]]\nchannel = \"pressure\"\nkind = \"gremlins\"\n").find("bad.toml:3"),
            std::string::npos);
  EXPECT_NE(ErrorOf("[[faults]]\nchannel = \"temperature\"\nkind = \"stuck\"\n").find("channel must be"),
            std::string::npos);
  EXPECT_NE(ErrorOf("[acquisition]\nperiods = 2.5\n").find("expected an integer"), std::string::npos);

  test::TempDir dir;
  try {
    ReadTruthFile(dir.file("missing.toml"));
    FAIL();
  } catch (const TruthError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.toml"), std::string::npos);
  }
}

TEST(SimTruth, RigSettingsAndFaultsAreRead) {
  const Truth t = ParseTruth(R"(
[actuator]
ideal = true
[sensors.pressure]
range = [0.0, 25.0e6]
noise = 0.0
bits = 0
[acquisition]
sample_rate = 400.0
periods = 2
gauge_pressure = false
[[faults]]
experiment = "c"
channel = "force"
kind = "spikes"
start = 1.0
rate = 3.0
amplitude = 0.05
)",
                             "rig.toml");
  EXPECT_TRUE(t.actuator.ideal);
  EXPECT_DOUBLE_EQ(t.sensors.pressure.range_max, 25e6);
  EXPECT_EQ(t.sensors.pressure.bits, 0);
  EXPECT_DOUBLE_EQ(t.acquisition.sample_rate, 400.0);
  EXPECT_EQ(t.acquisition.periods, 2);
  EXPECT_FALSE(t.acquisition.gauge_pressure);
  ASSERT_EQ(t.faults.size(), 1u);
  EXPECT_EQ(t.faults[0].kind, FaultKind::kSpikes);
  EXPECT_TRUE(t.faults[0].Applies("c", "force"));
  EXPECT_FALSE(t.faults[0].Applies("d", "force"));
  EXPECT_FALSE(t.faults[0].Applies("c", "stroke"));
}

}  // namespace
}  // namespace strut::sim
