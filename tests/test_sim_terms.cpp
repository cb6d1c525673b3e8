// The extra physics terms of the simulated rig (viscous-damping, stribeck-friction, end-stop,
// oil-compressibility, real-gas): their equations as documented, and exact derivatives checked
// against finite differences at instants where each term is active (near full extension, at low
// speed, at deep compression), which test_model.cpp's mid-stroke instant does not reach.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <span>

#include "model_instants.h"
#include "strut/ident/model.h"

namespace strut::ident {
namespace {

constexpr const char* kAll = "viscous-damping+stribeck-friction+end-stop+oil-compressibility+real-gas";
// The terms for physics beyond the paper (damper-physics.md §2) that compose with both bases.
constexpr const char* kBeyondThePaper = "dead-volume+charge-loss+recoil-damping+metering-pin+friction-asymmetry";

using test::Instant;
using test::ResidualAt;

// An instant with stroke q, rate v, pressure p, temperature T (whatever the causality).
Instant At(const Model& model, double q, double v, double a, double p, double T, double F) {
  Instant s;
  for (int j = 0; j < model.unknown_count(); ++j) {
    const std::string name = model.unknown_spec(j).name;
    s.x.push_back(name == "stroke" ? q : name == "force" ? F : name == "pressure" ? p : T);
    s.xd.push_back(name == "stroke" ? v : name == "temperature" ? 0.3 : 0.0);
    s.xdd.push_back(name == "stroke" ? a : 0.0);
  }
  if (model.causality() == Causality::kForceInput) {
    s.u = F, s.ud = 150.0, s.udd = -10.0;
  } else {
    const int offset = model.defaults().position_of_index(12);
    s.u = q + (offset >= 0 ? model.defaults().value(offset) : 0.0), s.ud = v, s.udd = a;
  }
  return s;
}

struct ActiveInstant {
  double q, v, a, p, T, F;
};

// Exact derivatives of every residual against central differences, in every variable and parameter.
// `step`: the central differences' step in the unknowns and the input, relative to their values.
void ExpectJetDerivativesMatchFiniteDifferences(const Model& model, std::span<const ActiveInstant> instants,
                                                double step = 1e-6) {
  const std::vector<double> theta = model.defaults().values();
  const int m = model.unknown_count(), np = model.parameter_count();
  ASSERT_LE(test::JetDirections(model), kMaxDerivatives);
  for (const auto& in : instants) {
    SCOPED_TRACE(model.composition() + " " + std::string(ToString(model.causality())) + " q = " + std::to_string(in.q) +
                 " v = " + std::to_string(in.v));
    const Instant s = At(model, in.q, in.v, in.a, in.p, in.T, in.F);
    const std::vector<Jet> r = test::ResidualJets(model, s, theta);
    // Central differences with a step of `step` relative to each variable (of 1e-3 at the least); for a
    // parameter 1e-4 relative to its value or typical size: an oil compliance of 8e-10 1/Pa needs
    // a step far below 1e-9 (the truncation error at 10 MPa) but above 1e-15 (the rounding error
    // at the charge pressure, where its effect is a few Pa in 0.7 MPa).
    const auto check = [&](int direction, auto&& perturb, double base_value, const std::string& what,
                           double floor = 1e-3, double relative = -1.0) {
      if (relative < 0) relative = step;
      const double h = relative * std::max(std::abs(base_value), floor);
      Instant plus = s, minus = s;
      std::vector<double> tp = theta, tm = theta;
      perturb(plus, tp, h);
      perturb(minus, tm, -h);
      const auto rp = ResidualAt(model, plus, tp), rm = ResidualAt(model, minus, tm);
      for (int i = 0; i < m; ++i) {
        const double numeric = (rp[i] - rm[i]) / (2 * h), exact = r[i].derivatives()[direction];
        EXPECT_NEAR(exact, numeric, 2e-6 * std::max(1.0, std::abs(exact)) + 1e-7 * model.equation_scale(i) * 1e6)
            << "equation " << i << " w.r.t. " << what;
      }
    };
    for (int j = 0; j < m; ++j) {
      check(j, [&](Instant& t, std::vector<double>&, double h) { t.x[j] += h; }, s.x[j], "x" + std::to_string(j));
      check(m + j, [&](Instant& t, std::vector<double>&, double h) { t.xd[j] += h; }, s.xd[j],
            "xd" + std::to_string(j));
      check(2 * m + j, [&](Instant& t, std::vector<double>&, double h) { t.xdd[j] += h; }, s.xdd[j],
            "xdd" + std::to_string(j));
    }
    check(3 * m, [&](Instant& t, std::vector<double>&, double h) { t.u += h; }, s.u, "u");
    check(3 * m + 1, [&](Instant& t, std::vector<double>&, double h) { t.ud += h; }, s.ud, "u'");
    for (int i = 0; i < np; ++i)
      check(3 * m + 3 + i, [&](Instant&, std::vector<double>& t, double h) { t[i] += h; }, theta[i],
            model.defaults().spec(i).key(), model.defaults().spec(i).typical_size(), 1e-4);
  }
}

TEST(SimTerms, JetDerivativesMatchFiniteDifferencesWhereEachTermIsActive) {
  // In contact with the top-out stop at low speed (end-stop, Stribeck), and deep in the stroke at
  // high pressure and temperature (oil compliance, real gas).
  const ActiveInstant instants[] = {{-2e-5, 0.0021, 0.4, 7.1e5, 296.0, 2400.0},
                                    {0.24, -0.0035, -0.3, 5.5e6, 385.0, 28000.0}};
  for (const char* base : {"1dof", "2dof"})
    for (Causality causality : {Causality::kForceInput, Causality::kStrokeInput})
      ExpectJetDerivativesMatchFiniteDifferences(Model::Build(std::string(base) + "+" + kAll, causality), instants);
}

TEST(SimTerms, TermsBeyondThePaperHaveExactDerivativesInBothDirectionsOfTravel) {
  // Extension and compression at speed deep in the stroke (recoil valve, metering pin, heat
  // transfer at high pressure, the dead volume), and near a reversal (friction asymmetry). Steps of
  // 1e-5: the metering pin's stroke derivative at the reversal is 0.02 N/m in forces of kN, which a
  // step of 1e-6 resolves only to the rounding error of the balance (about 2e-5 N/m).
  const ActiveInstant instants[] = {{0.2, -0.12, 0.5, 4.0e6, 360.0, 20000.0},
                                    {0.15, 0.09, -0.4, 2.5e6, 330.0, 15000.0},
                                    {0.05, -0.0008, 0.1, 1.0e6, 300.0, 5000.0}};
  for (Causality causality : {Causality::kForceInput, Causality::kStrokeInput}) {
    ExpectJetDerivativesMatchFiniteDifferences(Model::Build(std::string("1dof+") + kBeyondThePaper, causality),
                                               instants, 1e-5);
    ExpectJetDerivativesMatchFiniteDifferences(
        Model::Build(std::string("2dof+") + kBeyondThePaper + "+pressure-heat-transfer", causality), instants, 1e-5);
  }
}

TEST(SimTerms, ChargeLossLowersTheFreeGasWithTheExperimentsSessionTime) {
  const Model lossy = Model::Build("1dof+charge-loss", Causality::kStrokeInput);
  const Model plain = Model::Build("1dof", Causality::kStrokeInput);
  const std::vector<double> theta = lossy.defaults().values();
  const auto t = [&](int i) { return theta[lossy.defaults().position_of_index(i)]; };
  ASSERT_GT(t(37), 0.0);
  EXPECT_TRUE(lossy.defaults().spec(lossy.defaults().position_of_index(kSessionTimeIndex)).experiment_condition);
  // A model without the condition takes theta as it is.
  EXPECT_EQ(plain.AtExperiment(plain.defaults().values(), {0.7, 0.1}), plain.defaults().values());
  const auto pressure = [&](double session_time) {
    return lossy.StaticEquilibrium(0.12, lossy.AtExperiment(theta, {session_time, 0.0}))[1];
  };
  // At the session's start the charge is the plain model's; later p = theta5 ((1 - theta37 s) / V)^theta7.
  const double start = plain.StaticEquilibrium(0.12, plain.defaults().values())[1];
  EXPECT_NEAR(pressure(0.0), start, 1e-9 * start);
  for (double s : {0.5, 1.0})
    EXPECT_NEAR(pressure(s) / start, std::pow(1.0 - t(37) * s, t(7)), 1e-9) << "session time " << s;
}

// Force of the balance of a stroke-input model at an instant, i.e. sum of term forces (F = 0 given).
double TermForces(const Model& model, const std::vector<double>& theta, double q, double v, double p, double T) {
  Instant s = At(model, q, v, 0.0, p, T, 0.0);
  s.x[0] = 0.0;
  return ResidualAt(model, s, theta)[0];
}

TEST(SimTerms, ForceTermsFollowTheirDocumentedEquations) {
  const Model plain = Model::Build("2dof", Causality::kStrokeInput);
  const Model more = Model::Build("2dof+viscous-damping+stribeck-friction+end-stop", Causality::kStrokeInput);
  const ParameterSet& d = more.defaults();
  const auto t = [&](int i) { return d.value(d.position_of_index(i)); };
  const std::vector<double> base = plain.defaults().values(), theta = d.values();
  for (const double q : {-3e-4, 0.0, 5e-4, 0.1}) {
    for (const double v : {-0.05, -0.002, 0.0005, 0.004, 0.1}) {
      const double p = 9e5, T = 300.0;
      const double extra = TermForces(more, theta, q, v, p, T) - TermForces(plain, base, q, v, p, T);
      const double coulomb = (t(8) + t(9) * p) * std::atan(t(10) * v);
      const double stribeck = t(19) * coulomb * std::exp(-(v / t(20)) * (v / t(20)));
      const double w = t(24), depth = w * std::log1p(std::exp((t(23) - q) / w));
      const double stop = -t(21) * depth * (1.0 - t(22) * v);  // damping theta22 times the stiffness
      EXPECT_NEAR(extra, t(18) * v + stribeck + stop, 1e-9 * (1.0 + std::abs(extra))) << "q " << q << " v " << v;
    }
  }
  // The stop is inert a millimetre inside full extension and holds the gas preload just beyond it.
  EXPECT_LT(std::abs(TermForces(more, theta, 1e-3, 0.0, 7e5, 293.15) - TermForces(plain, base, 1e-3, 0.0, 7e5, 293.15)),
            0.5);
  EXPECT_LT(TermForces(more, theta, -1e-3, 0.0, 7e5, 293.15), -1500.0);
}

TEST(SimTerms, OilComplianceAndRealGasChangeThePressureAsDocumented) {
  // Static gas pressure at a deep stroke and the charge: oil compliance gives the gas room
  // (lower pressure), the virial N2 is stiffer than ideal where it is dense and hot.
  const auto pressure = [](const std::string& composition, double stroke, double temperature_offset) {
    const Model model = Model::Build(composition, Causality::kStrokeInput);
    std::vector<double> theta = model.defaults().values();
    theta[model.defaults().position_of_index(17)] -= temperature_offset;  // hotter wall
    return model.StaticEquilibrium(stroke, theta)[1];
  };
  const double ideal = pressure("2dof", 0.25, 0.0);
  const double oil = pressure("2dof+oil-compressibility", 0.25, 0.0);
  EXPECT_LT(oil, ideal);
  // V_g / V0 = 1 + theta6 q + (V_oil / V0)(p - p_ref) C, C = 1/K: solve the ideal-gas law with it.
  const Model m = Model::Build("2dof+oil-compressibility", Causality::kStrokeInput);
  const ParameterSet& d = m.defaults();
  const auto t = [&](int i) { return d.value(d.position_of_index(i)); };
  const double T = -t(17), V = 1 + t(6) * 0.25 + t(25) * t(26) * (oil - t(27));
  EXPECT_NEAR(oil, t(5) * T * (1 - t(7) * oil / t(5)) / V, 1e-6 * oil);
  EXPECT_NEAR(ideal / oil - 1, (V - (1 + t(6) * 0.25)) / (1 + t(6) * 0.25), 2e-3);

  // Real gas: Z = 1 + g ((b0 - a / T) rho + c rho^2), g = theta31 = 1; below 1 at the charge (B < 0 at 293 K), above 1
  // deep in the stroke at 400 K.
  EXPECT_LT(pressure("2dof+real-gas", 0.0, 0.0), pressure("2dof", 0.0, 0.0));
  const double hot_ideal = pressure("2dof", 0.25, 107.0), hot_real = pressure("2dof+real-gas", 0.25, 107.0);
  EXPECT_GT(hot_real, hot_ideal * 1.01);
  const Model r = Model::Build("2dof+real-gas", Causality::kStrokeInput);
  const ParameterSet& rd = r.defaults();
  const auto rt = [&](int i) { return rd.value(rd.position_of_index(i)); };
  const double T400 = 293.15 + 107.0, N = 1 - rt(7) * hot_real / rt(5), V400 = 1 + rt(6) * 0.25;
  const double rho = rt(5) * N / (8.314462618 * V400);
  const double Z = 1 + rt(31) * ((rt(28) - rt(29) / T400) * rho + rt(30) * rho * rho);
  EXPECT_NEAR(hot_real, rt(5) * T400 * N * Z / V400, 1e-6 * hot_real);
  EXPECT_GT(Z, 1.01);
  EXPECT_LT(Z, 1.06);  // damper-physics.md §2.10: Z of about 1.03 at 10 MPa and 400 K
}

TEST(SimTerms, TermsComposeWithBothBasesAndNameTheirRequirements) {
  for (const char* base : {"1dof", "2dof"})
    for (const char* term : {"viscous-damping", "stribeck-friction", "end-stop", "oil-compressibility", "real-gas",
                             "dead-volume", "recoil-damping", "metering-pin", "friction-asymmetry"}) {
      const Model model = Model::Build(std::string(base) + "+" + term, Causality::kForceInput);
      EXPECT_TRUE(model.has_term(term)) << base << "+" << term;
      // Every parameter has a name, a unit and a finite default.
      for (const auto& spec : model.defaults().specs()) {
        EXPECT_FALSE(spec.name.empty());
        EXPECT_FALSE(spec.unit.empty());
        EXPECT_TRUE(std::isfinite(spec.default_value));
      }
    }
  const Model all = Model::Build(std::string("2dof+") + kAll, Causality::kStrokeInput);
  for (int index = 18; index <= 31; ++index) EXPECT_GE(all.defaults().position_of_index(index), 0) << index;
  // Real gas under the polytropic law multiplies the pressure by Z (not Z^n).
  const Model poly = Model::Build("1dof+real-gas", Causality::kStrokeInput);
  const Model ideal = Model::Build("1dof", Causality::kStrokeInput);
  const double p_real = poly.StaticEquilibrium(0.2, poly.defaults().values())[1];
  const double p_ideal = ideal.StaticEquilibrium(0.2, ideal.defaults().values())[1];
  const ParameterSet& d = poly.defaults();
  const auto t = [&](int i) { return d.value(d.position_of_index(i)); };
  const double rho = t(5) / (8.314462618 * 293.15) / (1 + t(6) * 0.2);
  EXPECT_NEAR(p_real / p_ideal, 1 + (t(28) - t(29) / 293.15) * rho + t(30) * rho * rho, 1e-4);
}

TEST(SimTerms, DampingAndFrictionAsymmetriesFollowTheirDocumentedEquations) {
  const Model plain = Model::Build("2dof", Causality::kStrokeInput);
  const Model more = Model::Build("2dof+recoil-damping+metering-pin+friction-asymmetry", Causality::kStrokeInput);
  const ParameterSet& d = more.defaults();
  const auto t = [&](int i) { return d.value(d.position_of_index(i)); };
  const std::vector<double> base = plain.defaults().values(), theta = d.values();
  for (const double q : {0.0, 0.1, 0.25}) {
    for (const double v : {-0.12, -0.002, 0.0, 0.0005, 0.1}) {
      const double p = 2e6, T = 300.0;
      const double extra = TermForces(more, theta, q, v, p, T) - TermForces(plain, base, q, v, p, T);
      const double recoil = v < 0 ? -t(32) * t(3) * v * v : 0.0;  // (1 + theta32) theta3 q'|q'| in extension
      const double pin = t(33) * t(3) * q * v * std::abs(v);
      const double a = std::atan(t(10) * v);
      const double asymmetry = t(34) * (t(8) + t(9) * p) * 2.0 / std::numbers::pi * a * a;
      EXPECT_NEAR(extra, recoil + pin + asymmetry, 1e-9 * (1.0 + std::abs(extra))) << "q " << q << " v " << v;
    }
  }
  // The extension damping is (1 + theta32) times the compression damping at the same speed.
  const Model recoil = Model::Build("2dof+recoil-damping", Causality::kStrokeInput);
  const std::vector<double> r = recoil.defaults().values();
  const double rest = TermForces(recoil, r, 0.1, 0.0, 2e6, 300.0);
  const double out = TermForces(recoil, r, 0.1, -0.1, 2e6, 300.0) - rest, in = TermForces(recoil, r, 0.1, 0.1, 2e6, 300.0) - rest;
  const double friction = 2.0 * (t(8) + t(9) * 2e6) * std::atan(t(10) * 0.1);  // odd: in minus out
  EXPECT_NEAR(-(out + 0.5 * friction) / (in - 0.5 * friction), 1.0 + t(32), 1e-3);
}

TEST(SimTerms, DeadVolumeSoftensTheGasAtDeepCompressionAndHeatTransferGrowsWithPressure) {
  // The static pressure at the charge is the same with and without the dead volume, and lower deep
  // in the stroke (isothermal storage of the polytropic law): the exponent falls with compression.
  const auto pressure = [](const std::string& composition, double stroke) {
    const Model model = Model::Build(composition, Causality::kStrokeInput);
    return model.StaticEquilibrium(stroke, model.defaults().values())[1];
  };
  EXPECT_NEAR(pressure("1dof+dead-volume", 0.0), pressure("1dof", 0.0), 1e-6 * pressure("1dof", 0.0));
  const double deep = pressure("1dof", 0.25), with = pressure("1dof+dead-volume", 0.25);
  EXPECT_LT(with, deep);
  // N = 1 - r (p / theta5 - 1) in p = theta5 (N / V)^n: solve for the pressure it gives.
  const Model m = Model::Build("1dof+dead-volume", Causality::kStrokeInput);
  const ParameterSet& d = m.defaults();
  const auto t = [&](int i) { return d.value(d.position_of_index(i)); };
  const double n = 1.0 - t(36) * (with / t(5) - 1.0), V = 1.0 + t(6) * 0.25;
  EXPECT_NEAR(with, t(5) * std::pow(n / V, t(7)), 1e-6 * with);
  // 2 dof at ambient temperature: the dead volume is part of V0 and changes nothing.
  EXPECT_NEAR(pressure("2dof+dead-volume", 0.25), pressure("2dof", 0.25), 1e-6 * pressure("2dof", 0.25));

  // Pressure-dependent heat transfer: the heat balance's conductance term grows by
  // theta35 ((p / p_c)^(2/3) - 1), p_c = -theta5 theta17.
  const Model plain = Model::Build("2dof", Causality::kStrokeInput);
  const Model more = Model::Build("2dof+pressure-heat-transfer", Causality::kStrokeInput);
  const ParameterSet& h = more.defaults();
  const auto ht = [&](int i) { return h.value(h.position_of_index(i)); };
  const double q = 0.25, p = 8e6, T = 380.0;
  const Instant s0 = At(plain, q, 0.0, 0.0, p, T, 0.0), s1 = At(more, q, 0.0, 0.0, p, T, 0.0);
  const double r0 = ResidualAt(plain, s0, plain.defaults().values())[2];
  const double r1 = ResidualAt(more, s1, h.values())[2];
  const double conduction = ht(16) * (1.0 + ht(6) * q) * (T + ht(17));
  const double growth = std::pow(p / (-ht(5) * ht(17)), 2.0 / 3.0) - 1.0;
  EXPECT_NEAR(r1 - r0, ht(35) * growth * conduction, 1e-9 * std::abs(conduction));
  // damper-physics.md §2.1: 4-5 times the heat transfer at deep compression (8 MPa).
  EXPECT_GT(1.0 + growth, 4.0);
  EXPECT_LT(1.0 + growth, 6.0);
}

}  // namespace
}  // namespace strut::ident
