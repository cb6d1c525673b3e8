// Drawn units (sim/draw.h): reproducible from the seed, spread as the documented table says,
// feasible for the standard matrix, and recorded in the sessions the rig produces from them.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <fstream>
#include <functional>
#include <map>
#include <numbers>

#include "strut/daq/session.h"
#include "strut/ident/model.h"
#include "strut/sim/draw.h"
#include "strut/sim/recorded_truth.h"
#include "strut/sim/simulated_rig.h"
#include "test_support.h"

namespace strut::sim {
namespace {

constexpr double kPatm = 101325.0;

ident::ParameterSet Values(const Truth& t) { return t.Parameters(t.BuildModel(ident::Causality::kStrokeInput)); }
double Get(const Truth& t, std::string_view name) { return Values(t).get(name); }

//! Mean and standard deviation a spread gives, in the space it is uniform or normal in (log of
//! the factor for log-uniform spreads), relative to the base value.
std::pair<double, double> Expected(const DrawSpread& s) {
  switch (s.kind) {
    case SpreadKind::kUniformFactor:
    case SpreadKind::kUniformOffset: return {(s.low + s.high) / 2, (s.high - s.low) / std::sqrt(12.0)};
    case SpreadKind::kLogUniformFactor:
      return {(std::log(s.low) + std::log(s.high)) / 2, (std::log(s.high) - std::log(s.low)) / std::sqrt(12.0)};
    case SpreadKind::kNormalOffset: {
      // N(0, sd) clipped at +-c: the variance loses the tails beyond c.
      const double c = s.high / s.low, phi = std::exp(-c * c / 2) / std::sqrt(2 * M_PI);
      const double tail = std::erfc(c / std::sqrt(2.0));
      return {0.0, s.low * std::sqrt(1 - tail - 2 * c * phi + c * c * tail)};
    }
  }
  return {0, 0};
}

const DrawSpread& Spread(std::string_view quantity) {
  for (const auto& s : DrawSpreads())
    if (s.quantity == quantity) return s;
  throw std::out_of_range(std::string(quantity));
}

UnitDraw AllEffects() {
  UnitDraw spec;
  spec.base = "2dof";
  for (const char* e : {"oil-compressibility", "viscous-damping", "stribeck-friction", "end-stop", "real-gas"})
    spec.effects.push_back({e, std::nullopt});
  return spec;
}

//! The drawn quantity of each spread, read back from a unit (in the space of Expected()).
std::map<std::string, double> Quantities(const Truth& unit, const Truth& base) {
  const ident::ParameterSet u = Values(unit), b = Values(base);
  std::map<std::string, double> q;
  const auto factor = [&](const char* name) { return u.get(name) / b.get(name); };
  q["moving_mass"] = factor("moving_mass");
  q["orifice_damping"] = std::log(factor("orifice_damping"));
  q["gas_area"] = factor("gas_area");
  const auto ratio = [](const ident::ParameterSet& p) { return 1.0 / (1.0 + p.get("theta6") * kFullStroke); };
  q["compression_ratio"] = ratio(u) / ratio(b);
  if (u.find("gas_solubility")) q["gas_solubility"] = factor("gas_solubility");
  if (u.find("polytropic_exponent")) q["polytropic_exponent"] = u.get("polytropic_exponent") - 1.2;
  for (const char* name : {"friction_base", "friction_pressure", "friction_sharpness"}) q[name] = factor(name);
  q["load_cell_zero"] = (u.get("theta11") + kPatm * u.get("theta4")) - (b.get("theta11") + kPatm * b.get("theta4"));
  q["stroke_offset"] = u.get("theta12");  // drawn around the lab's nominal zero, not the shipped -2 mm
  if (u.find("gas_heat_capacity")) {
    q["gas_heat_capacity"] = factor("gas_heat_capacity");
    q["wall_heat_conductance"] = factor("wall_heat_conductance");
  }
  if (u.find("viscous_damping")) q["viscous_damping"] = std::log(factor("viscous_damping"));
  if (u.find("stribeck_excess")) q["stribeck_excess"] = factor("stribeck_excess");
  if (u.find("end_stop_stiffness")) q["end_stop_stiffness"] = std::log(factor("end_stop_stiffness"));
  if (u.find("oil_compliance")) q["oil_compliance"] = factor("oil_compliance");
  return q;
}

//! Checks mean and sd of every quantity in `only` (all when empty) against the table, within
//! four standard errors.
void ExpectSpreads(const std::vector<std::map<std::string, double>>& samples, const std::vector<std::string>& only) {
  std::map<std::string, std::vector<double>> by_quantity;
  for (const auto& s : samples)
    for (const auto& [k, v] : s) by_quantity[k].push_back(v);
  for (const auto& [name, values] : by_quantity) {
    if (!only.empty() && std::find(only.begin(), only.end(), name) == only.end()) continue;
    const auto [mean, sd] = Expected(Spread(name));
    const double n = static_cast<double>(values.size());
    double m = 0, v = 0;
    for (double x : values) m += x;
    m /= n;
    for (double x : values) v += (x - m) * (x - m);
    const double s = std::sqrt(v / (n - 1));
    EXPECT_NEAR(m, mean, 4 * sd / std::sqrt(n)) << name;
    EXPECT_NEAR(s, sd, 4 * sd / std::sqrt(2 * n)) << name;
  }
}

TEST(SimDraw, TheSameSeedGivesTheSameUnitAndOtherSeedsOthers) {
  const Truth a = DrawUnit(AllEffects(), 11), b = DrawUnit(AllEffects(), 11), c = DrawUnit(AllEffects(), 12);
  EXPECT_EQ(Values(a).values(), Values(b).values());
  EXPECT_NE(Values(a).values(), Values(c).values());
  ASSERT_TRUE(a.drawn);
  EXPECT_EQ(a.drawn->seed, 11u);
  EXPECT_EQ(a.Composition(), "2dof+viscous-damping+stribeck-friction+end-stop+oil-compressibility+real-gas");
  // The drawn unit keeps the rig of the truth it was drawn around.
  const Truth shipped = DefaultTruth();
  EXPECT_EQ(a.actuator.force_limit, shipped.actuator.force_limit);
  EXPECT_EQ(a.sensors.force.noise, shipped.sensors.force.noise);
  EXPECT_EQ(a.acquisition.sample_rate, shipped.acquisition.sample_rate);
  EXPECT_EQ(Get(a, "gravity"), Get(shipped, "gravity"));
  EXPECT_EQ(Get(a, "minus_ambient_temperature"), Get(shipped, "minus_ambient_temperature"));
}

TEST(SimDraw, RawSpreadsMatchTheDocumentedTable) {
  // Without the feasibility rule every quantity follows its table row exactly.
  const Truth base = DefaultTruth();
  UnitDraw spec = AllEffects();
  spec.feasible_only = false;
  UnitDraw one = spec;
  one.base = "1dof";
  std::vector<std::map<std::string, double>> samples;
  for (std::uint64_t seed = 1; seed <= 500; ++seed) {
    samples.push_back(Quantities(DrawUnit(seed % 2 ? spec : one, seed), base));
  }
  ExpectSpreads(samples, {});
  // The charge: the preload as a fraction of the drop budget m g - Coulomb friction.
  const Truth unit = DrawUnit(spec, 3);
  const ident::Model model = unit.BuildModel(ident::Causality::kStrokeInput);
  const ident::ParameterSet p = unit.Parameters(model);
  const double p0 = model.StaticEquilibrium(p.get("theta12"), p.values())[1];
  const double k = (p0 - kPatm) * p.get("theta4") /
                   (350 * 9.81 - (p.get("theta8") + p.get("theta9") * p0) * M_PI / 2);
  EXPECT_GT(k, 0.8 * 0.95);
  EXPECT_LE(k, 0.975);
}

TEST(SimDraw, EveryDrawnUnitIsFeasibleAndUnconstrainedSpreadsHold) {
  const auto start = std::chrono::steady_clock::now();
  const Truth base = DefaultTruth();
  std::vector<std::map<std::string, double>> samples;
  int attempts = 0;
  const int units = 500;
  for (std::uint64_t seed = 1; seed <= units; ++seed) {
    const Truth unit = DrawUnit(base, UnitDraw{}, seed);
    attempts += unit.drawn->attempts;
    const Feasibility f = CheckFeasibility(unit, rig::StandardMatrix(), 350.0);
    EXPECT_TRUE(f.feasible) << seed << ": " << f.reason;
    EXPECT_GE(f.compression_ratio, 5.0);
    EXPECT_LE(f.compression_ratio, 12.0);
    EXPECT_LT(f.peak_force, 45e3);
    EXPECT_GE(f.drop_margin, 0.0);
    samples.push_back(Quantities(unit, base));
  }
  // Quantities the rule does not look at keep their documented spread.
  ExpectSpreads(samples, {"moving_mass", "orifice_damping", "friction_sharpness", "load_cell_zero",
                          "gas_solubility", "wall_heat_conductance"});
  RecordProperty("acceptance", units * 1.0 / attempts);
  std::printf("%d feasible units from %d candidates (%.0f %% accepted) in %.1f s\n", units, attempts,
              100.0 * units / attempts,
              std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  // About half: the stroke zero is drawn around the lab's nominal 0 (sd 2 mm), and a zero more than
  // about 3 mm high puts experiment n's true stroke within 1 mm of full extension (rejected).
  EXPECT_GT(static_cast<double>(units) / attempts, 0.4);
}

TEST(SimDraw, OneDofUnitsAreFeasibleToo) {
  UnitDraw spec;
  spec.base = "1dof";
  int attempts = 0;
  const int units = 100;
  for (std::uint64_t seed = 1; seed <= units; ++seed) {
    const Truth unit = DrawUnit(spec, seed);
    attempts += unit.drawn->attempts;
    const Feasibility f = CheckFeasibility(unit, rig::StandardMatrix(), 350.0);
    EXPECT_TRUE(f.feasible) << seed << ": " << f.reason;
  }
  std::printf("1dof: %d feasible units from %d candidates (%.0f %% accepted)\n", units, attempts,
              100.0 * units / attempts);
}

TEST(SimDraw, AGivenEffectSizeIsInTheTruthAndTheComposition) {
  UnitDraw spec;
  spec.effects = {{"viscous-damping", 200.0}, {"end-stop", std::nullopt}};
  const Truth unit = DrawUnit(spec, 5);
  EXPECT_EQ(unit.Composition(), "2dof+viscous-damping+end-stop");
  EXPECT_EQ(Get(unit, "viscous_damping"), 200.0);
  ASSERT_EQ(unit.drawn->effects.size(), 2u);
  EXPECT_EQ(unit.drawn->effects[0].effect, "viscous-damping");
  EXPECT_EQ(unit.drawn->effects[0].parameter, "theta18");
  EXPECT_TRUE(unit.drawn->effects[0].given);
  EXPECT_FALSE(unit.drawn->effects[1].given);
  EXPECT_EQ(unit.drawn->effects[1].size, Get(unit, "end_stop_stiffness"));
}

TEST(SimDraw, BasesShareTheirCommonQuantitiesForOneSeed) {
  UnitDraw one;
  one.base = "1dof";
  one.feasible_only = false;
  UnitDraw two;
  two.feasible_only = false;
  const Truth a = DrawUnit(one, 9), b = DrawUnit(two, 9);
  EXPECT_EQ(a.Composition(), "1dof");
  EXPECT_EQ(Get(a, "gas_area"), Get(b, "gas_area"));
  EXPECT_EQ(Get(a, "moving_mass"), Get(b, "moving_mass"));
  EXPECT_GE(Get(a, "polytropic_exponent"), 1.05);
  EXPECT_LE(Get(a, "polytropic_exponent"), 1.35);
}

TEST(SimDraw, MistakesInTheSpecAreNamed) {
  UnitDraw spec;
  spec.base = "3dof";
  EXPECT_THROW(
      {
        try {
          DrawUnit(spec, 1);
        } catch (const TruthError& e) {
          EXPECT_NE(std::string(e.what()).find("'3dof'"), std::string::npos) << e.what();
          throw;
        }
      },
      TruthError);
  spec.base = "2dof";
  spec.effects = {{"warp-drive", std::nullopt}};
  EXPECT_THROW(DrawUnit(spec, 1), TruthError);
  spec.effects = {{"viscous-damping", -3.0}};
  EXPECT_THROW(DrawUnit(spec, 1), TruthError);
}

// Viscous damping under stroke input adds theta18 q' to the force and leaves the gas alone, so its
// signal has a closed form: RMS theta18 a 2 pi f / sqrt(2) per experiment in the load cell's sd.
TEST(SimDraw, AnEffectsSignalIsItsDifferenceInTheDataInNoiseSd) {
  constexpr double kDamping = 400.0;  // N s/m
  UnitDraw spec;
  spec.effects = {{"viscous-damping", kDamping}};
  const Truth unit = DrawUnit(spec, 11);
  const std::vector<rig::MatrixEntry> matrix = rig::StandardMatrix();
  const EffectSignal signal = MeasureEffectSignal(unit, "viscous-damping", matrix);

  double largest = 0.0, chi2 = 0.0;
  std::string where;
  for (const rig::MatrixEntry& e : matrix) {
    const double rms = kDamping * e.amplitude * 2.0 * std::numbers::pi * e.frequency / std::sqrt(2.0);
    const double samples = unit.acquisition.periods * unit.acquisition.sample_rate / e.frequency;
    chi2 += samples * std::pow(rms / unit.sensors.force.noise, 2);
    if (rms > largest) largest = rms, where = e.label;
  }
  // The solver's difference operators carry the rate: backward2 on 800 points to about 2e-5.
  EXPECT_NEAR(signal.rms, largest / unit.sensors.force.noise, 1e-4 * signal.rms);
  EXPECT_NEAR(signal.chi2, chi2, 2e-4 * chi2);
  EXPECT_EQ(signal.experiment, where);
  EXPECT_EQ(signal.channel, "force");

  // Half the damping, half the signal; a noisier load cell, a smaller one.
  Truth half = unit, noisy = unit;
  half.parameters.emplace_back("theta18", kDamping / 2);  // applied after the drawn values
  noisy.sensors.force.noise *= 4.0;
  EXPECT_NEAR(MeasureEffectSignal(half, "viscous-damping", matrix).rms, signal.rms / 2, 1e-6 * signal.rms);
  EXPECT_NEAR(MeasureEffectSignal(noisy, "viscous-damping", matrix).rms, signal.rms / 4, 1e-6 * signal.rms);
}

// A stop the matrix never reaches leaves no signal; one it is driven into does.
TEST(SimDraw, AnEndStopsSignalIsHowFarTheMatrixDrivesIntoIt) {
  const auto signal_at = [](double position) {
    UnitDraw spec;
    spec.effects = {{"end-stop", std::nullopt}};
    Truth unit = DrawUnit(spec, 3);
    unit.parameters.emplace_back("theta23", position);
    return MeasureEffectSignal(unit, "end-stop", rig::StandardMatrix());
  };
  EXPECT_LT(signal_at(-0.01).rms, 1e-3);  // 10 mm beyond full extension: 100 smoothing lengths
  const EffectSignal deep = signal_at(0.015);  // the shallowest test reaches 4 mm + 5 mm of stroke zero
  EXPECT_GT(deep.rms, 10.0);
  EXPECT_EQ(deep.channel, "force");
  // A contact force at the bottom of a few experiments is nothing the baseline's terms can make.
  EXPECT_GT(deep.left_rms, 0.5 * deep.rms);
}

// The 2 dof gas law (theta5..theta7, the stroke zero) takes up most of a virial correction: what
// the baseline leaves is a small part of the difference (docs/discovery.md, "Detection sizes").
TEST(SimDraw, TheBaselineAbsorbsMostOfARealGas) {
  UnitDraw spec;
  spec.effects = {{"real-gas", 1.0}};
  const EffectSignal signal = MeasureEffectSignal(DrawUnit(spec, 11), "real-gas", rig::StandardMatrix());
  EXPECT_GT(signal.rms, 5.0);
  EXPECT_EQ(signal.channel, "pressure");
  EXPECT_GT(signal.left_rms, 0.0);
  EXPECT_LT(signal.left_rms, 0.2 * signal.rms);
}

TEST(SimDraw, ASignalOfAMissingEffectOrWithoutNoiseIsRefused) {
  UnitDraw spec;
  spec.effects = {{"real-gas", std::nullopt}};
  Truth unit = DrawUnit(spec, 2);
  const auto message = [&](std::string_view effect) {
    return test::ErrorOf<TruthError>([&] { MeasureEffectSignal(unit, effect, rig::StandardMatrix()); });
  };
  EXPECT_NE(message("viscous-damping").find("no effect 'viscous-damping'"), std::string::npos) << message("viscous-damping");
  unit.sensors.pressure.noise = 0.0;
  EXPECT_NE(message("real-gas").find("pressure channel has no noise"), std::string::npos) << message("real-gas");
}

TEST(SimDraw, TheSessionRecordsTheTruthTheRigSimulated) {
  test::TempDir dir;
  UnitDraw spec;
  spec.effects = {{"viscous-damping", 200.0}};
  const SimulatedRig rig(DrawUnit(spec, 21));
  rig::MatrixPlan plan;
  plan.experiments = {{"j", "middle", 2.0, 0.133, 0.010}};
  plan.periods = 1;
  const daq::Session written = rig.RunMatrix(plan);
  daq::WriteSession(dir.file("s.h5"), written);
  const daq::Session session = daq::ReadSession(dir.file("s.h5"));
  const auto truth = ReadRecordedTruth(session);
  ASSERT_TRUE(truth);
  EXPECT_EQ(truth->composition, "2dof+viscous-damping");
  // Bit for bit what the plant ran, and the load cell's zero as theta39 (the plant feels none).
  EXPECT_EQ(truth->parameters.values(), rig.truth().RecordedParameters(rig.model()).values());
  std::vector<double> plant = truth->parameters.values();
  plant[truth->parameters.position_of_index(39)] = 0.0;
  EXPECT_EQ(plant, rig.theta());
  EXPECT_EQ(truth->parameters.get("theta39"), rig.truth().sensors.force.offset);
  EXPECT_EQ(truth->parameters.get("theta18"), 200.0);
  ASSERT_TRUE(truth->drawn);
  EXPECT_EQ(truth->drawn->seed, 21u);
  EXPECT_EQ(truth->drawn->base, "2dof");
  ASSERT_EQ(truth->drawn->effects.size(), 1u);
  EXPECT_EQ(truth->drawn->effects[0].effect, "viscous-damping");
  EXPECT_EQ(truth->drawn->effects[0].size, 200.0);
  EXPECT_TRUE(truth->drawn->effects[0].given);
  // Numbers are stored as numbers; names beside the keys.
  const daq::MetadataGroup* group = session.find_metadata("truth")->find_group("parameters")->find_group("theta4");
  ASSERT_NE(group, nullptr);
  EXPECT_TRUE(std::holds_alternative<double>(group->attributes.at("value")));
  EXPECT_EQ(group->text("name"), "gas_area");
  // A rewrite keeps the truth.
  daq::WriteSession(dir.file("again.h5"), session);
  EXPECT_EQ(ReadRecordedTruth(daq::ReadSession(dir.file("again.h5")))->parameters.values(), truth->parameters.values());
}

TEST(SimDraw, ASessionWithoutATruthGroupHasNoRecordedTruth) {
  daq::Session session;
  EXPECT_FALSE(ReadRecordedTruth(session));
  // The shipped truth is recorded too, as not drawn.
  rig::MatrixPlan plan;
  plan.experiments = {{"j", "middle", 2.0, 0.133, 0.010}};
  plan.periods = 1;
  Truth shipped = DefaultTruth();
  shipped.actuator.ideal = true;
  const SimulatedRig rig(shipped);
  const auto truth = ReadRecordedTruth(rig.RunMatrix(plan));
  ASSERT_TRUE(truth);
  EXPECT_FALSE(truth->drawn);
  EXPECT_EQ(truth->parameters.values(), shipped.RecordedParameters(rig.model()).values());
  EXPECT_EQ(truth->parameters.get("theta39"), 60.0);  // the shipped load cell's zero
}

}  // namespace
}  // namespace strut::sim
