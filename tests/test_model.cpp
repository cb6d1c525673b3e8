// Damper models: composition, parameters, and exact derivatives against central finite differences.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "model_instants.h"
#include "strut/ident/model.h"
#include "test_support.h"

namespace strut::ident {
namespace {

struct Case {
  std::string composition;
  Causality causality;
  std::string changes = "";  // applied to the defaults (--set syntax)
};

std::vector<Case> AllCases() {
  std::vector<Case> cases;
  for (const char* c : {"1dof", "2dof", "1dof+heat-exchange", "2dof+end-stop+viscous-damping",
                        "1dof+end-stop+viscous-damping+stribeck-friction", "1dof+oil-compressibility+real-gas",
                        "2dof+stribeck-friction+oil-compressibility+real-gas",
                        "2dof+viscous-damping+stribeck-friction+end-stop+oil-compressibility+real-gas"})
    for (Causality k : {Causality::kForceInput, Causality::kStrokeInput}) cases.push_back({c, k});
  // The instant's stroke 0.131 m 4 mm inside the stop: its position and stiffness act.
  for (Causality k : {Causality::kForceInput, Causality::kStrokeInput})
    cases.push_back({"2dof+end-stop+stribeck-friction+real-gas", k, "theta23=0.135"});
  // The empirical discrepancy's whole library, every coefficient away from 0, half-way through the
  // session (its drifts act), at a static position of 150 mm (its static functions act).
  const std::string library = "theta70=0.3,theta71=-0.2,theta72=0.1,theta73=0.2,theta74=0.4,theta75=-0.3,theta76=0.5,"
                              "theta77=0.1,theta78=-0.1,theta79=0.05,theta80=-0.02,theta81=0.01,theta82=0.004,"
                              "theta83=-0.002,theta84=0.01,theta85=-0.005,theta86=0.01,theta87=-0.005,theta88=0.004,"
                              "theta89=-0.002,theta90=0.005,theta93=0.2,theta94=-0.1,theta95=0.15,theta96=0.3,"
                              "theta97=0.1315,theta98=0.2,theta38=0.5,theta40=0.15";
  // The heat-flow functions act where the model has a heat balance.
  const std::string heat_flow = ",theta91=0.8,theta92=0.7";
  const std::string gas_temperature = ",theta99=0.2";
  for (Causality k : {Causality::kForceInput, Causality::kStrokeInput}) {
    cases.push_back({"2dof+discrepancy", k, library + heat_flow + gas_temperature});
    // Beside its catalogue twin the heat-flow function (and its exponent) is left out.
    cases.push_back({"2dof+pressure-heat-transfer+discrepancy", k, library + gas_temperature});
    cases.push_back({"1dof+discrepancy", k, library});
  }
  return cases;
}

using test::Instant;
using test::ResidualAt;

// A realistic instant in mid-stroke, moving: every term is active.
Instant MakeInstant(const Model& model) {
  Instant p;
  const int m = model.unknown_count();
  for (int j = 0; j < m; ++j) {
    const StateSpec s = model.unknown_spec(j);
    double value = s.typical_value;
    if (s.name == "pressure") value = 1.3e6;
    if (s.name == "temperature") value = 301.0;
    if (s.name == "stroke") value = 0.131;
    if (s.name == "force") value = 6500.0;
    p.x.push_back(value);
    p.xd.push_back(s.name == "stroke" ? 0.031 : (s.name == "temperature" ? 0.7 : 0.0));
    p.xdd.push_back(s.name == "stroke" ? -0.21 : 0.0);
  }
  if (model.causality() == Causality::kForceInput) {
    p.u = 6500.0, p.ud = 300.0, p.udd = -20.0;
  } else {
    p.u = 0.131, p.ud = 0.031, p.udd = -0.21;
  }
  return p;
}

TEST(Model, ComposesBasesAndTermsCanonically) {
  EXPECT_EQ(Model::Build("2dof", Causality::kForceInput).composition(), "2dof");
  EXPECT_EQ(Model::Build("1dof+heat-exchange+gas-solubility", Causality::kForceInput).composition(), "2dof");
  EXPECT_EQ(Model::Build("1dof+heat-exchange", Causality::kForceInput).composition(), "1dof+heat-exchange");
  const Model one = Model::Build("1dof", Causality::kForceInput);
  EXPECT_EQ(one.output_channels(), (std::vector<std::string>{"stroke", "force", "pressure"}));
  const Model two = Model::Build("2dof", Causality::kStrokeInput);
  EXPECT_EQ(two.output_channels(), (std::vector<std::string>{"stroke", "force", "pressure", "temperature"}));
  EXPECT_EQ(two.unknown_spec(0).name, "force");
}

TEST(Model, ParametersFollowThePaperNumbering) {
  const Model one = Model::Build("1dof", Causality::kForceInput);
  const Model two = Model::Build("2dof", Causality::kForceInput);
  EXPECT_EQ(one.defaults().spec(one.defaults().position("theta7")).name, "polytropic_exponent");
  EXPECT_EQ(two.defaults().spec(two.defaults().position("theta7")).name, "gas_solubility");
  EXPECT_EQ(two.defaults().spec(two.defaults().position("theta5")).unit, "Pa/K");
  EXPECT_EQ(two.defaults().position("gas_area"), two.defaults().position("theta4"));
  EXPECT_EQ(two.defaults().position_of_index(16), two.defaults().position("wall_heat_conductance"));
  EXPECT_FALSE(one.defaults().find("theta16").has_value());
}

TEST(Model, RejectsUnknownTermsAndDuplicates) {
  EXPECT_THROW(Model::Build("3dof", Causality::kForceInput), ModelError);
  try {
    Model::Build("1dof+warp-drive", Causality::kForceInput);
    FAIL();
  } catch (const ModelError& e) {
    EXPECT_NE(std::string(e.what()).find("warp-drive"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("heat-exchange"), std::string::npos);  // lists the catalogue
  }
  EXPECT_THROW(Model::Build("2dof+heat-exchange", Causality::kForceInput), ModelError);
  EXPECT_THROW(Model::Build("1dof+gas-solubility", Causality::kForceInput), ModelError);
}

TEST(Model, SetAssignmentsAcceptIndexAndName) {
  ParameterSet p = Model::Build("2dof", Causality::kForceInput).defaults();
  p.apply_assignments("theta4=0.006, wall_heat_conductance=3.5,16=4");
  EXPECT_DOUBLE_EQ(p.get("gas_area"), 0.006);
  EXPECT_DOUBLE_EQ(p.get("theta16"), 4.0);
  EXPECT_THROW(p.apply_assignments("theta99=1"), ParameterError);
  EXPECT_THROW(p.apply_assignments("theta4=abc"), ParameterError);
  EXPECT_THROW(p.apply_assignments("theta4"), ParameterError);
}

// docs/parameters.md: blank text sets nothing; an empty item is refused naming the whole text, and
// nothing of the list is applied (the same rule as --calibration, test_session_fit).
TEST(Model, SetAssignmentsRefuseAnEmptyItem) {
  ParameterSet p = Model::Build("2dof", Causality::kForceInput).defaults();
  const double theta4 = p.get("theta4");
  p.apply_assignments(" ");
  EXPECT_EQ(p.get("theta4"), theta4);
  for (const char* bad : {"theta4=0.006,,theta16=4", "theta4=0.006,", ",theta4=0.006", "theta4=0.006, ,16=4"}) {
    SCOPED_TRACE(bad);
    try {
      p.apply_assignments(bad);
      ADD_FAILURE() << "accepted";
    } catch (const ParameterError& e) {
      EXPECT_NE(std::string(e.what()).find(std::string("--set: '") + bad + "' has an empty item"), std::string::npos)
          << e.what();
    }
    EXPECT_EQ(p.get("theta4"), theta4);
  }
  try {
    p.apply_assignments("theta4=0.006,=4");
    ADD_FAILURE() << "accepted";
  } catch (const ParameterError& e) {
    EXPECT_NE(std::string(e.what()).find("--set: '=4' is not NAME=VALUE"), std::string::npos) << e.what();
  }
}

TEST(Model, ParameterFileErrorsNameTheLine) {
  test::TempDir dir;
  const std::string path = dir.file("p.txt");
  std::ofstream(path) << "# lab charge\ntheta4 = 0.0052 estimate sd=1e-4\ngas_area_typo = 3\n";
  ParameterSet p = Model::Build("2dof", Causality::kForceInput).defaults();
  try {
    p.apply_file(path);
    FAIL();
  } catch (const ParameterError& e) {
    EXPECT_NE(std::string(e.what()).find(path + ":3"), std::string::npos) << e.what();
  }
  std::ofstream(path) << "theta4 = 0.0052 estimate sd=1e-4\ntheta16 = 2.5 fixed\n";
  p.apply_file(path);
  EXPECT_DOUBLE_EQ(p.get("theta4"), 0.0052);
  const auto entries = ReadParameterFile(path);
  ASSERT_EQ(entries.size(), 2u);
  EXPECT_TRUE(*entries[0].estimate);
  EXPECT_DOUBLE_EQ(*entries[0].prior_sd, 1e-4);
  EXPECT_FALSE(*entries[1].estimate);
  std::ofstream(path) << "theta4 = 0.0052 maybe\n";
  EXPECT_THROW(ReadParameterFile(path), ParameterError);
}

TEST(ParameterRanges, EveryDefaultLiesInItsPhysicalRange) {
  for (const Case& c : AllCases()) {
    const ParameterSet d = Model::Build(c.composition, c.causality).defaults();
    EXPECT_EQ(d.RangeViolation(), std::nullopt) << c.composition;
  }
  for (const char* oscillator : {"linear-oscillator+quadratic-stiffness+cubic-stiffness+cubic-damping+input-offset",
                                 "linear-oscillator+output-offset"}) {
    const ParameterSet d = Model::Build(oscillator, Causality::kForceInput).defaults();
    EXPECT_EQ(d.RangeViolation(), std::nullopt) << oscillator;
  }
}

TEST(ParameterRanges, DeclareTheirBounds) {
  const ParameterSet d =
      Model::Build("2dof+viscous-damping+stribeck-friction+end-stop+oil-compressibility+real-gas",
                   Causality::kStrokeInput)
          .defaults();
  const auto range = [&](const char* key) { return d.spec(d.position(key)).range; };
  EXPECT_EQ(range("moving_mass").ToString(), "(0, inf)");
  EXPECT_EQ(range("theta4").ToString(), "(0, inf)");
  EXPECT_EQ(range("theta6").ToString(), "(-inf, 0)");
  EXPECT_EQ(range("theta21").ToString(), "[0, inf)");
  EXPECT_EQ(range("theta26").ToString(), "[0, inf)");
  EXPECT_EQ(range("theta11").ToString(), "(-inf, inf)");
  EXPECT_FALSE(range("theta11").bounded());
  EXPECT_TRUE(range("theta4").contains(1e-3));
  EXPECT_FALSE(range("theta4").contains(0.0));
  EXPECT_TRUE(range("theta21").contains(0.0));
  EXPECT_FALSE(range("theta6").contains(0.0));
  EXPECT_FALSE(range("theta21").contains(NAN));
  EXPECT_FALSE(range("theta17").contains(1.0));  // minus a temperature in kelvin
}

TEST(ParameterRanges, SetAndFilesRefuseAValueOutsideTheRange) {
  ParameterSet p = Model::Build("2dof", Causality::kStrokeInput).defaults();
  try {
    p.apply_assignments("theta16=3,theta4=-1");
    FAIL();
  } catch (const ParameterError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("theta4 gas_area = -1 m^2 is outside its physical range (0, inf)"), std::string::npos)
        << what;
  }
  EXPECT_DOUBLE_EQ(p.get("theta16"), 2.24);  // all or nothing
  test::TempDir dir;
  const std::string path = dir.file("p.txt");
  std::ofstream(path) << "theta16 = 3\ntheta6 = 0.5\n";
  try {
    p.apply_file(path);
    FAIL();
  } catch (const ParameterError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(path + ":2: theta6 volume_per_stroke = 0.5 1/m is outside its physical range (-inf, 0)"),
              std::string::npos)
        << what;
  }
  EXPECT_DOUBLE_EQ(p.get("theta16"), 2.24);
  p.values()[p.position("theta1")] = 0.0;  // set() bypasses the check; Validate() finds it
  EXPECT_THROW(p.Validate(), ParameterError);
  EXPECT_NE(p.RangeViolation()->find("theta1 moving_mass = 0 kg"), std::string::npos);
}

TEST(SizeParameters, ZeroSwitchesTheEffectOffAndTheResidualIsLinearThere) {
  // Every size parameter of a candidate term: at 0 the residual is that of the model without the
  // term, and the residual at 0, s/2 and s lie on a line (to a few percent of the change).
  const std::string base = "2dof";
  for (const char* term : {"viscous-damping", "stribeck-friction", "end-stop", "oil-compressibility", "real-gas",
                           "dead-volume", "recoil-damping", "metering-pin", "friction-asymmetry", "pressure-heat-transfer"}) {
    SCOPED_TRACE(term);
    const Model with = Model::Build(base + "+" + term, Causality::kStrokeInput);
    const Model without = Model::Build(base, Causality::kStrokeInput);
    Instant p = MakeInstant(with);
    p.x[1] = 2.5e6;           // deep compression: the gas terms matter
    p.u = 0.004, p.ud = 0.02;  // and the stroke inside a stop at 6 mm
    std::vector<double> theta = with.defaults().values();
    if (with.defaults().find("theta23")) theta[with.defaults().position("theta23")] = 0.006;
    int sizes = 0;
    for (int i = 0; i < with.parameter_count(); ++i) {
      const ParameterSpec& spec = with.defaults().spec(i);
      if (!spec.sizes_term || without.defaults().find(spec.key())) continue;  // the term's own size
      ++sizes;
      EXPECT_TRUE(spec.range.contains(0.0)) << spec.key();
      std::vector<double> zero = theta, half = theta;
      zero[i] = 0.0;
      half[i] = 0.5 * theta[i];
      std::vector<double> base_theta;
      for (const ParameterSpec& b : without.defaults().specs())
        base_theta.push_back(zero[with.defaults().position(b.key())]);
      const auto r0 = ResidualAt(with, p, zero), rh = ResidualAt(with, p, half), r1 = ResidualAt(with, p, theta);
      const auto rb = ResidualAt(without, p, base_theta);
      for (std::size_t e = 0; e < r0.size(); ++e) {
        EXPECT_NEAR(r0[e], rb[e], 1e-9 * std::max(1.0, std::abs(rb[e]))) << spec.key() << " equation " << e;
        const double change = std::abs(r1[e] - r0[e]);
        EXPECT_NEAR(rh[e] - r0[e], 0.5 * (r1[e] - r0[e]), 0.05 * change + 1e-9) << spec.key() << " equation " << e;
      }
    }
    EXPECT_EQ(sizes, 1);
  }
}

TEST(SizeParameters, ShapeParametersAreMarkedAndScaled) {
  const ParameterSet d =
      Model::Build("2dof+stribeck-friction+end-stop", Causality::kStrokeInput).defaults();
  for (const char* key : {"theta20", "theta23"}) {
    const ParameterSpec& s = d.spec(d.position(key));
    EXPECT_TRUE(s.shapes_term) << key;
    EXPECT_TRUE(s.estimated_with_term()) << key;
    EXPECT_GT(s.typical_size(), 1e-3) << key;
    EXPECT_LT(s.typical_size(), 1e-2) << key;
  }
  for (const char* key : {"theta22", "theta24"}) EXPECT_FALSE(d.spec(d.position(key)).estimated_with_term()) << key;
}

TEST(Model, ResidualMatchesTheEquationsOfTheMethod) {
  // 2 dof, force input: g1, the gas law and g2 written out by hand (method.md eqs. 23, 24).
  const Model model = Model::Build("2dof", Causality::kForceInput);
  const ParameterSet& d = model.defaults();
  const auto t = [&](int i) { return d.value(d.position_of_index(i)); };
  const double q = 0.12, qd = 0.05, qdd = 0.3, p = 1.5e6, T = 305.0, Td = 0.4, F = 8000.0;
  std::vector<double> r(3);
  model.Residual<double>(std::vector<double>{q, p, T}, std::vector<double>{qd, 0.0, Td},
                         std::vector<double>{qdd, 0.0, 0.0}, F, 0.0, 0.0, d.values(), r);
  const double g1 = t(1) * (qdd + t(2)) + t(3) * qd * std::abs(qd) + t(4) * p +
                    (t(8) + t(9) * p) * std::atan(t(10) * qd) + t(11) - F;
  // p V = theta5 T N with the free gas N = 1 - theta7 p / theta5.
  const double gas = p - (t(5) * T - t(7) * p * T) / (1.0 + t(6) * q);
  const double g2 = t(15) * Td + t(16) * (1 + t(6) * q) * (T + t(17)) - (t(4) * p + t(11)) * qd;
  EXPECT_NEAR(r[0], g1, 1e-9 * std::abs(F));
  EXPECT_NEAR(r[1], gas, 1e-9 * p);
  EXPECT_NEAR(r[2], g2, 1e-9);
  // The gas law root is the paper's p = theta5 T / (1 + theta6 q + theta7 T).
  const double p_paper = t(5) * T / (1 + t(6) * q + t(7) * T);
  model.Residual<double>(std::vector<double>{q, p_paper, T}, std::vector<double>{qd, 0.0, Td},
                         std::vector<double>{qdd, 0.0, 0.0}, F, 0.0, 0.0, d.values(), r);
  EXPECT_NEAR(r[1], 0.0, 1e-8 * p_paper);
}

TEST(Model, ALoadCellZeroActsInTheForceBalanceOnlyAndTheForceOffsetInTheHeatBalanceToo) {
  const Model model = Model::Build("2dof", Causality::kForceInput);
  const double q = 0.12, qd = 0.05, qdd = 0.3, p = 1.5e6, T = 305.0, Td = 0.4, F = 8000.0;
  const auto residual = [&](int index, double value) {
    std::vector<double> theta = model.defaults().values();
    theta[model.defaults().position_of_index(index)] += value;
    std::vector<double> r(3);
    model.Residual<double>(std::vector<double>{q, p, T}, std::vector<double>{qd, 0.0, Td},
                           std::vector<double>{qdd, 0.0, 0.0}, F, 0.0, 0.0, theta, r);
    return r;
  };
  const std::vector<double> base = residual(39, 0.0), zero = residual(39, 60.0), offset = residual(11, 60.0);
  EXPECT_NEAR(zero[0] - base[0], 60.0, 1e-9 * F);
  EXPECT_NEAR(offset[0] - base[0], 60.0, 1e-9 * F);
  EXPECT_EQ(zero[1], base[1]);
  EXPECT_EQ(zero[2], base[2]);
  EXPECT_NEAR(offset[2] - base[2], -60.0 * qd, 1e-9);  // the work term (theta4 p + theta11) q'
  const ParameterSpec& spec = model.defaults().spec(model.defaults().position_of_index(39));
  EXPECT_EQ(spec.default_value, 0.0);
  EXPECT_EQ(spec.prior_sd, kLoadCellZeroPriorSd);
}

TEST(Model, JetDerivativesMatchCentralFiniteDifferences) {
  for (const Case& c : AllCases()) {
    SCOPED_TRACE(c.composition + " " + std::string(ToString(c.causality)) + " " + c.changes);
    const Model model = Model::Build(c.composition, c.causality);
    const int m = model.unknown_count();
    const int np = model.parameter_count();
    ParameterSet values = model.defaults();
    values.apply_assignments(c.changes);
    const std::vector<double> theta = values.values();
    const Instant p = MakeInstant(model);
    ASSERT_LE(test::JetDirections(model), kMaxDerivatives);
    const std::vector<Jet> r = test::ResidualJets(model, p, theta);

    // Step 1e-6 of the value, at least of `floor` (a parameter's typical size: an oil compliance
    // of 8e-10 1/Pa needs a step far below 1e-9).
    const auto fd = [&](auto&& perturb, double base, double floor = 1e-3) {
      const double h = 1e-6 * std::max(std::abs(base), floor);
      Instant plus = p, minus = p;
      std::vector<double> tp = theta, tm = theta;
      perturb(plus, tp, +h);
      perturb(minus, tm, -h);
      const auto rp = ResidualAt(model, plus, tp), rm = ResidualAt(model, minus, tm);
      std::vector<double> d(m);
      for (int i = 0; i < m; ++i) d[i] = (rp[i] - rm[i]) / (2 * h);
      return d;
    };
    const auto check = [&](int direction, const std::vector<double>& numeric, const std::string& what) {
      for (int i = 0; i < m; ++i) {
        const double exact = r[i].derivatives()[direction];
        EXPECT_NEAR(exact, numeric[i], 1e-6 * std::max(1.0, std::abs(exact)) + 1e-7 * model.equation_scale(i) * 1e6)
            << "equation " << i << " w.r.t. " << what;
      }
    };
    for (int j = 0; j < m; ++j) {
      check(j, fd([&](Instant& q, std::vector<double>&, double h) { q.x[j] += h; }, p.x[j]), "x" + std::to_string(j));
      check(m + j, fd([&](Instant& q, std::vector<double>&, double h) { q.xd[j] += h; }, p.xd[j]),
            "xd" + std::to_string(j));
      check(2 * m + j, fd([&](Instant& q, std::vector<double>&, double h) { q.xdd[j] += h; }, p.xdd[j]),
            "xdd" + std::to_string(j));
    }
    check(3 * m, fd([&](Instant& q, std::vector<double>&, double h) { q.u += h; }, p.u), "u");
    check(3 * m + 1, fd([&](Instant& q, std::vector<double>&, double h) { q.ud += h; }, p.ud), "ud");
    check(3 * m + 2, fd([&](Instant& q, std::vector<double>&, double h) { q.udd += h; }, p.udd), "udd");
    for (int i = 0; i < np; ++i)
      check(3 * m + 3 + i,
            fd([&](Instant&, std::vector<double>& t, double h) { t[i] += h; }, theta[i],
               model.defaults().spec(i).typical_size()),
            model.defaults().spec(i).key());
  }
}

TEST(Model, StaticEquilibriumBalancesTheGasForce) {
  const Model model = Model::Build("1dof", Causality::kForceInput);
  const ParameterSet& d = model.defaults();
  for (double force : {3000.0, 8000.0, 20000.0}) {
    const auto x = model.StaticEquilibrium(force, d.values());
    const double q = x[0], p = x[1];
    const auto t = [&](int i) { return d.value(d.position_of_index(i)); };
    EXPECT_NEAR(p, t(5) / std::pow(1 + t(6) * q, t(7)), 1e-6 * p);
    EXPECT_NEAR(t(1) * t(2) + t(4) * p + t(11), force, 1e-6);
    EXPECT_GT(q, -0.1);
    EXPECT_LT(q, 0.3);
  }
  const Model two = Model::Build("2dof", Causality::kForceInput);
  const auto x = two.StaticEquilibrium(15000.0, two.defaults().values());
  EXPECT_NEAR(x[2], 293.15, 1e-9);  // at rest the gas is at ambient temperature
}

}  // namespace
}  // namespace strut::ident
