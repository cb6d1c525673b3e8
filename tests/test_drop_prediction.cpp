// Drop-test prediction (sim/drop_prediction.h, strut predict drop, docs/drop-prediction.md): the
// figures of a drop against traces with known figures, the static stroke against the 1 dof gas law
// solved by hand, the intervals' linearisation against finer differences, the fit's JSON read back,
// and the proof of issue 15: a drop of a drawn unit's truth predicted from a shaker fit of the same
// unit within 5 % and inside the intervals.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "strut/report/fit_report.h"
#include "strut/ident/session_fit.h"
#include "strut/sim/draw.h"
#include "strut/sim/drop_prediction.h"
#include "session_fixtures.h"
#include "strut/sim/simulated_rig.h"
#include "test_support.h"

namespace strut::sim {
namespace {

//! A trace sampled every `dt` s up to t_end from functions of time.
template <class Q, class F>
DropTrace MakeTrace(double t_end, double dt, Q stroke, F force) {
  DropTrace t;
  for (int i = 0; i * dt <= t_end + 1e-12; ++i) {
    const double time = i * dt;
    t.time.push_back(time);
    t.stroke.push_back(stroke(time));
    t.force.push_back(force(time));
  }
  return t;
}

TEST(DropFigures, PeaksAreRefinedBetweenSamples) {
  // A parabolic force peak at 0.1234 s (between samples 10 ms apart) and a stroke peak likewise:
  // the parabola through three samples finds both exactly.
  const DropTrace t = MakeTrace(
      2.0, 0.01, [](double s) { return 0.04 - 0.5 * (s - 0.3071) * (s - 0.3071); },
      [](double s) { return 5000.0 - 2e4 * (s - 0.1234) * (s - 0.1234); });
  const DropFigures f = MeasureDrop(t, NAN, 0.01);
  EXPECT_NEAR(f.peak_force, 5000.0, 1e-9);
  EXPECT_NEAR(f.time_of_peak_force, 0.1234, 1e-12);
  EXPECT_NEAR(f.max_stroke, 0.04, 1e-12);
  EXPECT_NEAR(f.time_of_max_stroke, 0.3071, 1e-12);
  // The least stroke after the peak is the last sample: rebound = 0.5 (2 - 0.3071)^2.
  EXPECT_NEAR(f.rebound, 0.5 * (2.0 - 0.3071) * (2.0 - 0.3071), 1e-12);
  EXPECT_DOUBLE_EQ(f.final_stroke, t.stroke.back());
  EXPECT_TRUE(std::isnan(f.time_to_static));
  EXPECT_TRUE(std::isnan(f.peak_pressure));
}

TEST(DropFigures, TimeToStaticIsWhereTheStrokeStaysInTheBand) {
  // q = qs (1 + 0.5 exp(-t / 2)): outside 1 % of qs until t = 2 ln 50 = 7.824 s.
  const double qs = 0.05;
  const DropTrace t =
      MakeTrace(10.0, 0.01, [&](double s) { return qs * (1 + 0.5 * std::exp(-s / 2)); }, [](double) { return 1.0; });
  const DropFigures f = MeasureDrop(t, qs, 0.01);
  EXPECT_NEAR(f.time_to_static, 2 * std::log(50.0), 0.01 + 1e-9);
  EXPECT_GT(f.time_to_static, 2 * std::log(50.0));
  // Within 1 % of the last sample qs (1 + 0.5 e^-5) from exp(-t/2) = 0.02 (1 + 0.5 e^-5) + e^-5 on.
  const double t_final = -2 * std::log(0.02 * (1 + 0.5 * std::exp(-5.0)) + std::exp(-5.0));
  EXPECT_NEAR(f.time_to_final, t_final, 0.01 + 1e-9);
  EXPECT_GT(f.time_to_final, t_final);
  // A band never left: settled from contact; a band never reached: NaN.
  EXPECT_DOUBLE_EQ(MeasureDrop(t, qs, 0.6).time_to_static, 0.0);
  EXPECT_TRUE(std::isnan(MeasureDrop(t, qs, 0.001).time_to_static));
  DropTrace bad = t;
  bad.force.pop_back();
  EXPECT_THROW(MeasureDrop(bad, qs, 0.01), std::invalid_argument);
}

TEST(DropPrediction, StaticStrokeSolvesThePolytropicGasLawByHand) {
  // 1 dof: at rest M g = theta4 theta5 (1 + theta6 q)^-theta7 + theta11 (friction vanishes at rest).
  const ident::Model model = ident::Model::Build("1dof", ident::Causality::kForceInput);
  const std::vector<double> theta = model.defaults().values();
  const auto& d = model.defaults();
  DropPredictionOptions options;
  options.duration = 3.0;
  options.intervals = false;
  const DropPrediction p = PredictDrop(model, theta, 350.0, 0.5, {}, Eigen::MatrixXd(), options);
  const double g = theta[d.position_of_index(2)], area = theta[d.position_of_index(4)];
  const double p0 = theta[d.position_of_index(5)], k = theta[d.position_of_index(6)];
  const double n = theta[d.position_of_index(7)], offset = theta[d.position_of_index(11)];
  const double qs = (std::pow((350.0 * g - offset) / (area * p0), -1.0 / n) - 1.0) / k;
  EXPECT_NEAR(p.figures.static_stroke, qs, 1e-9);
  // Polytropic gas has no cooling: the stroke overshoots and settles about qs; at the deepest
  // point the gas pressure is the law's at that stroke.
  EXPECT_GT(p.figures.max_stroke, qs);
  EXPECT_NEAR(p.figures.peak_pressure, p0 * std::pow(1 + k * p.figures.max_stroke, -n), 1e-4 * p0);
  EXPECT_EQ(p.simulations, 1);
}

TEST(DropPrediction, MatchesTheSimulatedRigsDropOfTheSameDamper) {
  // The rig's drop (its own set-up of the same truth) and the prediction from the truth's values.
  const SimulatedRig rig(DefaultTruth());
  std::mt19937_64 rng(1);
  DropRunReport report;
  DropSpec spec;
  spec.duration = 5.0;
  rig.RunDrop(spec, rng, &report);
  const ident::Model model = DefaultTruth().BuildModel(ident::Causality::kForceInput);
  DropPredictionOptions options;
  options.duration = 5.0;
  options.intervals = false;
  const DropPrediction p = PredictDrop(model, rig.theta(), 350.0, 0.5, {}, Eigen::MatrixXd(), options);
  EXPECT_NEAR(p.figures.max_stroke, report.peak_stroke, 1e-4 * report.peak_stroke);
  EXPECT_NEAR(p.figures.peak_force, report.peak_force, 1e-3 * report.peak_force);
  EXPECT_NEAR(p.figures.final_stroke, report.final_stroke, 1e-4 * report.final_stroke);
}

TEST(DropPrediction, TheDroppedMassCarryingTheta1IsTheRigsDropOfBothMasses) {
  // Carrying theta1 (the shaker's 40 kg moving mass) is a drop of mass + theta1 on a rig where
  // theta1 stays on the ground: the simulated rig's own drop of 350 kg + theta1 is the reference.
  const ident::Model model = DefaultTruth().BuildModel(ident::Causality::kForceInput);
  const SimulatedRig rig(DefaultTruth());
  const double theta1 = rig.theta()[model.defaults().position_of_index(1)];
  ASSERT_GT(theta1, 1.0);
  std::mt19937_64 rng(1);
  DropRunReport report;
  DropSpec spec;
  spec.duration = 5.0;
  spec.mass = 350.0 + theta1;
  rig.RunDrop(spec, rng, &report);
  DropPredictionOptions options;
  options.duration = 5.0;
  options.intervals = false;
  const DropPrediction alone = PredictDrop(model, rig.theta(), 350.0, 0.5, {}, Eigen::MatrixXd(), options);
  options.moving_mass = DropMovingMass::kDroppedWithTheta1;
  const DropPrediction carried = PredictDrop(model, rig.theta(), 350.0, 0.5, {}, Eigen::MatrixXd(), options);
  EXPECT_NEAR(carried.load.mass, 350.0 + theta1, 1e-12);
  EXPECT_NEAR(carried.figures.max_stroke, report.peak_stroke, 1e-4 * report.peak_stroke);
  EXPECT_NEAR(carried.figures.peak_force, report.peak_force, 1e-3 * report.peak_force);
  EXPECT_NEAR(carried.figures.final_stroke, report.final_stroke, 1e-4 * report.final_stroke);
  // And it is not the drop of 350 kg alone: the heavier mass goes deeper.
  EXPECT_GT(carried.figures.max_stroke - alone.figures.max_stroke, 1e-3);
  EXPECT_EQ(DropMovingMassFrom("dropped+theta1"), DropMovingMass::kDroppedWithTheta1);
  EXPECT_EQ(DropMovingMassFrom("dropped"), DropMovingMass::kDroppedAlone);
  EXPECT_FALSE(DropMovingMassFrom("both").has_value());
}

TEST(DropPrediction, IntervalGradientAgreesWithFinerDifferences) {
  // sd^2 = g' C g with g by differences over +- 1 sd; with a 1 % sd on theta3 and theta4 the figures
  // are close to linear, so differences over +- 0.01 sd give the same gradient.
  const ident::Model model = DefaultTruth().BuildModel(ident::Causality::kForceInput);
  const SimulatedRig rig(DefaultTruth());
  const std::vector<double> theta = rig.theta();
  const auto& d = model.defaults();
  const std::vector<int> estimated{d.position_of_index(3), d.position_of_index(4)};
  Eigen::Matrix2d c;
  const double s3 = 0.01 * theta[estimated[0]], s4 = 0.01 * theta[estimated[1]];
  c << s3 * s3, 0.3 * s3 * s4, 0.3 * s3 * s4, s4 * s4;
  DropPredictionOptions options;
  options.duration = 2.0;
  const DropPrediction p = PredictDrop(model, theta, 350.0, 0.5, estimated, c, options);
  ASSERT_EQ(p.interval_parameters, (std::vector<std::string>{"theta3", "theta4"}));
  EXPECT_EQ(p.simulations, 5);
  options.intervals = false;
  const auto figures = [&](int a, double step) {
    std::vector<double> t = theta;
    t[estimated[a]] += step;
    return FigureValues(PredictDrop(model, t, 350.0, 0.5, {}, Eigen::MatrixXd(), options).figures);
  };
  for (int a = 0; a < 2; ++a) {
    const double h = 0.01 * std::sqrt(c(a, a));
    const std::vector<double> up = figures(a, h), down = figures(a, -h);
    for (int f : {0, 2}) {  // peak_force, max_stroke
      const double fine = (up[f] - down[f]) / (2 * h);
      EXPECT_NEAR(p.gradient(f, a), fine, 0.02 * std::abs(fine)) << DropFigureNames()[f].name << " a=" << a;
    }
  }
  const Eigen::VectorXd g = p.gradient.row(0).transpose();
  EXPECT_NEAR(p.uncertainty[0].sd, std::sqrt(g.dot(c * g)), 1e-12 * p.figures.peak_force);
  EXPECT_NEAR(p.uncertainty[0].upper - p.figures.peak_force, 1.959964 * p.uncertainty[0].sd, 1e-5 * p.uncertainty[0].sd);
  // Orifice damping raises the impact force: a positive gradient.
  EXPECT_GT(p.gradient(0, 0), 0.0);
}

TEST(DropWhatIf, AScaledParameterCarriesItsSdAndTheUnscaledFitIsPredictedBeside) {
  // Theta at positions 0..3, positions 1 and 3 estimated with covariance c; scale 1 by 2 and 2
  // (not estimated) by 0.5: theta 1 and 2 change, c's row and column of 1 double (its sd doubles,
  // its correlation with 3 stays).
  const std::vector<double> theta{1.0, 10.0, 100.0, 1000.0};
  Eigen::Matrix2d c;
  c << 4.0, 1.5, 1.5, 9.0;
  const ScaledParameters s = ScaleParameters(theta, {1, 3}, c, {{1, 2.0}, {2, 0.5}});
  EXPECT_EQ(s.theta, (std::vector<double>{1.0, 20.0, 50.0, 1000.0}));
  Eigen::Matrix2d expected;
  expected << 16.0, 3.0, 3.0, 9.0;
  EXPECT_EQ(s.covariance, expected);
  EXPECT_EQ(ScaleParameters(theta, {1, 3}, c, {}).covariance, c);
  EXPECT_THROW(ScaleParameters(theta, {}, Eigen::MatrixXd(), {{4, 2.0}}), std::invalid_argument);

  // Doubling theta3 of the default truth: the prediction is the scaled model's, the unscaled one
  // the fit's as it is (no intervals), the same as predicting each alone.
  const ident::Model model = DefaultTruth().BuildModel(ident::Causality::kForceInput);
  const SimulatedRig rig(DefaultTruth());
  const int p3 = model.defaults().position_of_index(3);
  DropPredictionOptions options;
  options.duration = 0.5;
  options.intervals = false;
  const WhatIfDrop w = PredictDropWhatIf(model, rig.theta(), 350.0, 0.5, {}, Eigen::MatrixXd(), {{p3, 2.0}}, options);
  ASSERT_TRUE(w.unscaled.has_value());
  std::vector<double> doubled = rig.theta();
  doubled[p3] *= 2.0;
  EXPECT_EQ(FigureValues(w.predicted.figures)[0],
            FigureValues(PredictDrop(model, doubled, 350.0, 0.5, {}, Eigen::MatrixXd(), options).figures)[0]);
  EXPECT_EQ(FigureValues(w.unscaled->figures)[0],
            FigureValues(PredictDrop(model, rig.theta(), 350.0, 0.5, {}, Eigen::MatrixXd(), options).figures)[0]);
  EXPECT_GT(w.predicted.figures.peak_force, w.unscaled->figures.peak_force);
  EXPECT_FALSE(PredictDropWhatIf(model, rig.theta(), 350.0, 0.5, {}, Eigen::MatrixXd(), {}, options).unscaled);
}

TEST(DropWhatIf, TheRecordedDropIsFoundOrRefusedNamingTheSession) {
  daq::Session session;
  daq::Experiment a, drop, other;
  a.label = "a";
  a.kind = daq::ExperimentKind::kPeriodic;
  drop.label = "d1";
  drop.kind = daq::ExperimentKind::kDrop;
  session.experiments = {a, drop};
  EXPECT_EQ(FindDropExperiment(session, "", "s.h5").label, "d1");
  EXPECT_EQ(FindDropExperiment(session, "d1", "s.h5").label, "d1");
  const auto refusal = [&](const std::string& label) {
    return test::ErrorOf<std::invalid_argument>([&] { FindDropExperiment(session, label, "s.h5"); });
  };
  EXPECT_EQ(refusal("a"), "--compare s.h5: experiment 'a' is not a drop");
  EXPECT_EQ(refusal("zz"), "--compare s.h5: no experiment 'zz'");
  other = drop;
  other.label = "d2";
  session.experiments.push_back(other);
  EXPECT_EQ(refusal(""), "--compare s.h5: several drop experiments ('d1', 'd2'); choose one with --experiment");
  EXPECT_EQ(FindDropExperiment(session, "d2", "s.h5").label, "d2");
  session.experiments = {a};
  EXPECT_EQ(refusal(""), "--compare s.h5: no drop experiment in the session");
}

TEST(FitJson, ReadsBackParametersAndCovariance) {
  nlohmann::json j = {{"model", "1dof"},
                      {"converged", true},
                      {"verdict", "at-noise-floor"},
                      {"parameters",
                       {{{"index", "theta3"}, {"value", 2000.0}, {"sd", 100.0}, {"estimated", true}},
                        {{"index", "theta4"}, {"value", 0.002}, {"sd", 1e-5}, {"estimated", true}},
                        {{"index", "theta7"}, {"value", 1.25}, {"sd", nullptr}, {"estimated", false}}}},
                      {"correlation", {{"parameters", {"theta4", "theta3"}}, {"matrix", {{1.0, -0.5}, {-0.5, 1.0}}}}}};
  const ident::FitRecord r = ident::ParseFitJson(j, "f.json", ident::Causality::kForceInput);
  EXPECT_EQ(r.model.composition(), "1dof");
  EXPECT_EQ(r.verdict, "at-noise-floor");
  EXPECT_DOUBLE_EQ(r.parameters.get("theta3"), 2000.0);
  EXPECT_DOUBLE_EQ(r.parameters.get("theta7"), 1.25);
  ASSERT_EQ(r.estimated_positions.size(), 2u);
  EXPECT_DOUBLE_EQ(r.covariance(0, 0), 100.0 * 100.0);
  EXPECT_DOUBLE_EQ(r.covariance(0, 1), -0.5 * 100.0 * 1e-5);
  EXPECT_DOUBLE_EQ(r.covariance(1, 1), 1e-10);
  // Errors name the file and the item.
  nlohmann::json bad = j;
  bad["parameters"][0]["index"] = "theta99";
  try {
    ident::ParseFitJson(bad, "f.json", ident::Causality::kForceInput);
    ADD_FAILURE() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("f.json"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("theta99"), std::string::npos);
  }
  bad = j;
  bad["correlation"]["matrix"] = {{1.0}};
  EXPECT_THROW(ident::ParseFitJson(bad, "f.json", ident::Causality::kForceInput), std::invalid_argument);
  EXPECT_THROW(ident::ParseFitJson(nlohmann::json::array(), "f.json", ident::Causality::kForceInput),
               std::invalid_argument);
}

// Issue 15's proof: a drawn unit's shaker matrix fitted as any unit would be, its truth dropped,
// the drop predicted from the fit. Peak force and maximum stroke within 5 % and inside the 95 %
// intervals.
TEST(DropPrediction, ShakerFitOfDrawnUnitsPredictsTheTruthsDrop) {
  for (const std::uint64_t seed : {1001u, 1002u}) {
    const Truth truth = test::DrawnIdealUnit(seed);
    const SimulatedRig rig(truth);
    RigRunOptions run;
    run.seed = seed;
    const daq::Session session = rig.RunMatrix(rig::StandardMatrixPlan(), run);
    ident::SessionFitOptions options;
    const ident::Model model = ident::Model::Build(options.composition, options.causality);
    const ident::SessionFit fit =
        ident::FitPrepared(ident::PrepareFitData(session, "unit", model, options.estimator.n), model, options);
    ASSERT_EQ(fit.summary.Verdict(), ident::FitVerdict::kAtNoiseFloor) << "unit " << seed;
    // Through the JSON as strut predict drop reads it.
    const ident::FitRecord record =
        ident::ParseFitJson(report::FitToJson(fit.summary), "unit", ident::Causality::kForceInput);

    std::mt19937_64 rng(seed);
    DropRunReport truth_drop;
    DropSpec spec;
    spec.duration = 10.0;
    rig.RunDrop(spec, rng, &truth_drop);
    DropTrace clean;
    const TransientResult& r = truth_drop.result;
    clean.time = r.time;
    clean.stroke.assign(r.unknowns.row(0).begin(), r.unknowns.row(0).end());
    clean.force.assign(r.input.begin(), r.input.end());
    const DropFigures want = MeasureDrop(clean, NAN, 0.01);

    DropPredictionOptions po;
    po.duration = 10.0;
    const DropPrediction p = PredictDrop(record.model, record.parameters.values(), spec.mass, spec.impact_velocity,
                                         record.estimated_positions, record.covariance, po);
    std::printf("  unit %lu: peak force %.1f N predicted %.1f +- %.1f; max stroke %.3f mm predicted %.3f +- %.3f\n",
                static_cast<unsigned long>(seed), want.peak_force, p.figures.peak_force, p.uncertainty[0].sd,
                1e3 * want.max_stroke, 1e3 * p.figures.max_stroke, 1e3 * p.uncertainty[2].sd);
    EXPECT_NEAR(p.figures.peak_force, want.peak_force, 0.05 * want.peak_force) << "unit " << seed;
    EXPECT_NEAR(p.figures.max_stroke, want.max_stroke, 0.05 * want.max_stroke) << "unit " << seed;
    EXPECT_GE(want.peak_force, p.uncertainty[0].lower) << "unit " << seed;
    EXPECT_LE(want.peak_force, p.uncertainty[0].upper) << "unit " << seed;
    EXPECT_GE(want.max_stroke, p.uncertainty[2].lower) << "unit " << seed;
    EXPECT_LE(want.max_stroke, p.uncertainty[2].upper) << "unit " << seed;
  }
}

}  // namespace
}  // namespace strut::sim
