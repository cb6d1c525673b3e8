// The one entry point for a fit from sessions, on units drawn away from the model's defaults.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <map>
#include <regex>

#include "session_fixtures.h"
#include "strut/ident/session_fit.h"
#include "strut/rig/test_matrix.h"
#include "strut/sim/draw.h"
#include "strut/sim/periodic_session.h"
#include "strut/sim/recorded_truth.h"
#include "strut/sim/simulated_rig.h"

namespace strut::ident {
namespace {

using test::DrawnIdealUnit;
using test::DrawnUnitSession;

TEST(SessionFit, TheThinnedGridOfTheSlowExperimentsFitsLikeEverySample) {
  // The default grid under stroke input keeps every sample phase only where the model may not be
  // smooth; the same fit on every sample phase (n = 200: experiment a at 5000 points) lands on the
  // same estimates, far within their sd, and the thinned grid is much smaller.
  const daq::Session session = DrawnUnitSession(23);
  SessionFitOptions options;
  const Model model = Model::Build(options.composition, options.causality);
  const FitData thinned = PrepareFitData(session, "drawn", model, options.estimator.n);
  SessionFitOptions every = options;
  every.estimator.n = 200;
  const FitData full = PrepareFitData(session, "drawn", model, every.estimator.n);
  std::size_t thinned_points = 0, full_points = 0;
  for (const ExperimentData& d : thinned.experiments) thinned_points += d.input.values.size();
  for (const ExperimentData& d : full.experiments) full_points += d.input.values.size();
  EXPECT_LT(thinned_points, full_points / 2);
  const SessionFit a = FitPrepared(thinned, model, options), b = FitPrepared(full, model, every);
  ASSERT_EQ(a.summary.Verdict(), FitVerdict::kAtNoiseFloor) << a.summary.FullReport();
  ASSERT_EQ(b.summary.Verdict(), FitVerdict::kAtNoiseFloor) << b.summary.FullReport();
  for (int i : a.summary.estimated_positions)
    EXPECT_LT(std::abs(a.summary.parameters.value(i) - b.summary.parameters.value(i)), 0.05 * b.summary.estimates[i].sd)
        << a.summary.parameters.spec(i).key();
}

//! The parameters of a drawn unit whose seal slides (friction sharpness 2000 s/m, not the draw's
//! near-stiction 1-3e4 s/m, where a force-driven stroke follows the load cell's noise in every stick
//! phase), for force input.
ParameterSet SlidingSealUnit(unsigned long seed, const Model& model) {
  ParameterSet truth = DrawnIdealUnit(seed).Parameters(model);
  truth.set("theta10", 2000.0);
  return truth;
}

//! Its standard matrix simulated from its periodic states with a load cell quiet enough for force
//! input (3 N against the gas stiffness times the LVDT's 0.03 mm: docs/identification.md, when
//! force input is worth it).
daq::Session QuietLoadCellSession(unsigned long seed) {
  const Model model = Model::Build("2dof", Causality::kStrokeInput);
  sim::PeriodicSessionOptions options;
  options.noise.force = 3.0;
  options.seed = static_cast<unsigned>(seed);
  return sim::SimulatePeriodicSession(model.composition(), SlidingSealUnit(seed, model).values(),
                                      rig::StandardMatrix(), options);
}

TEST(SessionFit, DefaultsIdentifyADrawnUnitToItsNoiseFloor) {
  for (const unsigned long seed : {21ul, 22ul}) {
    SCOPED_TRACE(seed);
    const daq::Session session = DrawnUnitSession(seed);
    const auto truth = sim::ReadRecordedTruth(session);
    ASSERT_TRUE(truth);
    SessionFitOptions options;  // 2dof, stroke input, every parameter the data determine
    const Model model = Model::Build(options.composition, options.causality);
    const SessionFit fit = FitPrepared(PrepareFitData(session, "drawn", model, options.estimator.n), model, options);
    ASSERT_EQ(fit.summary.Verdict(), FitVerdict::kAtNoiseFloor) << fit.summary.FullReport();
    // The wide set: all but gravity and the ambient temperature, the stroke zero with its prior.
    int estimated = 0;
    for (int i = 0; i < fit.plan.start.size(); ++i) {
      const int index = fit.plan.start.spec(i).index;
      EXPECT_EQ(fit.plan.choices[i].estimate, index != 2 && index != 17) << index;
      estimated += fit.plan.choices[i].estimate;
      if (index == 12) {
        ASSERT_TRUE(fit.plan.choices[i].prior_sd);
        EXPECT_EQ(*fit.plan.choices[i].prior_sd, kStrokeZeroPriorSd);
      }
    }
    EXPECT_EQ(estimated, 14);
    // Every estimate within 3.5 sd of the drawn truth (no parameter sits at a default).
    for (int i : fit.summary.estimated_positions) {
      const ParameterSpec& spec = fit.summary.parameters.spec(i);
      const double t = truth->parameters.get(spec.key());
      EXPECT_LT(std::abs(fit.summary.parameters.value(i) - t), 3.5 * fit.summary.estimates[i].sd)
          << spec.key() << " truth " << t << " estimate " << fit.summary.parameters.value(i) << " sd "
          << fit.summary.estimates[i].sd;
      if (spec.index != 12 && spec.index != 2 && spec.index != 17 && spec.index != 39)
        EXPECT_GT(std::abs(t / spec.default_value - 1.0), 1e-3) << spec.key() << " left at its default by the draw";
    }
    // The stroke zero's direction: theta6 (the volume per stroke) follows theta12. With the LVDT's
    // gain in the intervals (it scales the stroke theta6 multiplies) they part a little (|r| 0.98-0.99).
    const auto& est = fit.summary.estimated_positions;
    const auto at = [&](const char* key) {
      return static_cast<int>(std::find(est.begin(), est.end(), fit.summary.parameters.position(key)) - est.begin());
    };
    EXPECT_GT(std::abs(fit.summary.correlation(at("theta6"), at("theta12"))), 0.95);
    // Correlated parameters are warned about once per group: without the calibration the stroke
    // zero's direction links theta5, theta6, theta12 (and theta16: |r| > 0.99 pairwise), one warning,
    // not six.
    SessionFitOptions noise_only = options;
    noise_only.estimator.gain_sd.clear();
    const SessionFit uncalibrated = FitPlanned(fit.data, model, fit.plan, noise_only);
    std::map<std::string, int> mentions;
    int correlation_warnings = 0;
    for (const std::string& w : uncalibrated.summary.warnings) {
      if (w.find("are correlated") == std::string::npos) continue;
      ++correlation_warnings;
      for (int i : est) {
        const std::string key = fit.summary.parameters.spec(i).key();
        if (std::regex_search(w, std::regex("\\b" + key + "\\b"))) ++mentions[key];
      }
    }
    EXPECT_GE(correlation_warnings, 1) << uncalibrated.summary.FullReport();
    for (const auto& [key, count] : mentions) EXPECT_EQ(count, 1) << key << " in more than one correlation warning";
    for (const char* key : {"theta5", "theta6", "theta12"}) EXPECT_EQ(mentions[key], 1) << key;
  }
}

TEST(SessionFit, TheLoadCellZeroIsHeldByItsOwnParameterNotByTheMovingMass) {
  // The shipped load cell's 60 N zero on drawn unit 12 (ideal actuator, otherwise perfect
  // calibration). theta11 also does work on the gas in the heat balance, so a fit without theta39
  // cannot put the zero there alone and gives part of it to the weight theta1 g (+10 sd in theta1);
  // the default fit holds it in theta39, in the force balance only: the same noise recorded without
  // the zero is the reference, and the two default fits differ by the zero alone.
  const auto record = [](double zero) {
    sim::Truth unit = DrawnIdealUnit(12);
    unit.sensors.force.offset = zero;
    const sim::SimulatedRig rig(unit);
    sim::RigRunOptions run;
    run.seed = 1;
    return rig.RunMatrix(rig::StandardMatrixPlan(), run);
  };
  const daq::Session zeroed = record(60.0), clean = record(0.0);
  const auto truth = sim::ReadRecordedTruth(zeroed);
  ASSERT_TRUE(truth);
  EXPECT_EQ(truth->parameters.get("theta39"), 60.0);  // the recorded truth holds the sensor's zero
  const SessionFitOptions options;
  const Model model = Model::Build(options.composition, options.causality);
  const auto fit = [&](const daq::Session& session, bool with_zero) {
    FitData data = PrepareFitData(session, "zero", model, options.estimator.n);
    FitPlan plan = PlanFit(model, data, options);
    plan.choices[plan.start.position_of_index(39)].estimate = with_zero;
    SessionFit f = FitPlanned(std::move(data), model, std::move(plan), options);
    EXPECT_EQ(f.summary.Verdict(), FitVerdict::kAtNoiseFloor) << f.summary.FullReport();
    return f;
  };
  const auto value = [](const SessionFit& f, const char* key) {
    return f.summary.parameters.value(f.summary.parameters.position(key));
  };
  const auto sd = [](const SessionFit& f, const char* key) {
    return f.summary.estimates[f.summary.parameters.position(key)].sd;
  };
  const SessionFit without = fit(zeroed, false);
  EXPECT_GT((value(without, "theta1") - truth->parameters.get("theta1")) / sd(without, "theta1"), 5.0)
      << without.summary.FullReport();

  const SessionFit with = fit(zeroed, true), reference = fit(clean, true);
  for (const char* key : {"theta1", "theta3", "theta4", "theta11", "theta15", "theta16"})
    EXPECT_LT(std::abs(value(with, key) - value(reference, key)), 0.05 * sd(with, key)) << key;
  EXPECT_NEAR(value(with, "theta39") - value(reference, "theta39"), 60.0, 1.0);
  for (const char* key : {"theta1", "theta11", "theta39"})
    EXPECT_LT(std::abs(value(with, key) - truth->parameters.get(key)), 2.0 * sd(with, key))
        << key << "\n" << with.summary.FullReport();
}

TEST(SessionFit, RecordedZerosAreThePriorsOfTheStrokeZeroAndTheLoadCellZero) {
  // Drawn unit 12 through the shipped transducers (60 N load-cell zero); its LVDT zero theta12 is
  // drawn. The session records both zeros as a lab measures them: the fit starts there, with their
  // sds as priors, and the gas parameters the stroke zero is confounded with narrow.
  sim::Truth unit = DrawnIdealUnit(12);
  unit.sensors = sim::DefaultTruth().sensors;
  const sim::SimulatedRig rig(unit);
  sim::RigRunOptions run;
  run.seed = 1;
  const daq::Session plain = rig.RunMatrix(rig::StandardMatrixPlan(), run);
  const auto truth = sim::ReadRecordedTruth(plain);
  ASSERT_TRUE(truth);
  const double stroke_zero = truth->parameters.get("theta12"), stroke_sd = 2e-5;
  daq::Session zeroed = plain;
  daq::RecordZeros({.load_cell = daq::MeasuredZero{60.0 + 1.5, 3.0},
                    .stroke = daq::MeasuredZero{stroke_zero + 1e-5, stroke_sd}},
                   zeroed);
  const SessionFitOptions options;
  const Model model = Model::Build(options.composition, options.causality);
  const auto fit = [&](const daq::Session& session) {
    SessionFit f = FitPrepared(PrepareFitData(session, "zeros.h5", model, options.estimator.n), model, options);
    EXPECT_EQ(f.summary.Verdict(), FitVerdict::kAtNoiseFloor) << f.summary.FullReport();
    return f;
  };
  const SessionFit without = fit(plain), with = fit(zeroed);
  const auto at = [](const SessionFit& f, int index) { return f.summary.parameters.position_of_index(index); };
  const int s12 = at(with, kStrokeZeroIndex), s39 = at(with, kLoadCellZeroIndex);
  EXPECT_EQ(*with.plan.choices[s12].prior_sd, stroke_sd);
  EXPECT_EQ(*with.plan.choices[s39].prior_sd, 3.0);
  EXPECT_EQ(with.plan.start.value(s12), stroke_zero + 1e-5);
  EXPECT_NE(with.plan.sources[s12].find("zeros.h5 /calibration stroke_zero"), std::string::npos) << with.plan.sources[s12];
  EXPECT_EQ(*without.plan.choices[s12].prior_sd, kStrokeZeroPriorSd);
  // theta12 known to the reference's sd, and the truth inside its interval.
  EXPECT_LE(with.summary.estimates[s12].sd, stroke_sd * (1 + 1e-9));
  EXPECT_LT(std::abs(with.summary.parameters.value(s12) - stroke_zero), 2.0 * with.summary.estimates[s12].sd);
  EXPECT_LT(with.summary.estimates[s39].sd, 3.0);
  for (int index : {5, 6}) {
    // What the data and the model give: the lab's pressure calibration (0.2 %) is a floor of
    // theta5's whole interval that no stroke reference lowers.
    const double narrower = without.summary.NoiseSd(at(without, index)) / with.summary.NoiseSd(at(with, index));
    EXPECT_GT(narrower, 5.0) << "theta" << index << " narrower " << narrower << ", whole sd "
                             << without.summary.estimates[at(without, index)].sd / with.summary.estimates[at(with, index)].sd;
    const double z = (with.summary.parameters.value(at(with, index)) - truth->parameters.get(fmt::format("theta{}", index))) /
                     with.summary.estimates[at(with, index)].sd;
    EXPECT_LT(std::abs(z), 3.0) << "theta" << index;
  }
}

TEST(SessionFit, CalibrationPartOfEachSdIsWhatAGainErrorMovesTheEstimateBy) {
  // The independent reference: refit the same session with one transducer reading high (the gauge
  // pressure's reading, not the absolute pressure; the LVDT's whole reading q + theta12) and compare
  // each estimate's shift with the calibration part of its sd for a gain sd of that size. The
  // fitted outputs' gains act on their residuals, the input's (the stroke under stroke input, the
  // force under force input) through the measured and the estimated input.
  const daq::Session rig_session = DrawnUnitSession(23), quiet_session = QuietLoadCellSession(23);
  struct Case {
    Causality causality;
    const char* channel;
    double gain;
  };
  const Case cases[] = {{Causality::kStrokeInput, "force", 0.002},
                        {Causality::kStrokeInput, "pressure", 0.002},
                        {Causality::kStrokeInput, "stroke", 0.001},
                        {Causality::kForceInput, "stroke", 0.001},
                        {Causality::kForceInput, "force", 0.002}};
  std::map<Causality, SessionFit> bases;
  for (const Case& c : cases) {
    SCOPED_TRACE(fmt::format("{} input, {} gain {}", ToString(c.causality), c.channel, c.gain));
    const bool stroke_input = c.causality == Causality::kStrokeInput;
    const daq::Session& session = stroke_input ? rig_session : quiet_session;
    const Model model = Model::Build("2dof", c.causality);
    SessionFitOptions none;
    none.estimator.gain_sd.clear();
    none.causality = c.causality;
    if (!stroke_input) {
      none.estimate = "paper";
      // Force input, the paper's set from the truth: the wide set from the data's own start does not
      // converge there, and even this fit stays above the floor (stroke 3.3: force input's misfit,
      // docs/identification.md). The derivative is the optimum's, whatever its start and floor.
      const ParameterSet truth = SlidingSealUnit(23, model);
      for (int i = 0; i < truth.size(); ++i)
        none.assignments += fmt::format("{}{}={:.17g}", i ? "," : "", truth.spec(i).key(), truth.value(i));
    }
    if (!bases.count(c.causality)) {
      bases.emplace(c.causality, FitPrepared(PrepareFitData(session, "drawn", model, none.estimator.n), model, none));
      ASSERT_TRUE(bases.at(c.causality).summary.converged) << bases.at(c.causality).summary.FullReport();
      if (stroke_input) EXPECT_EQ(bases.at(c.causality).summary.Verdict(), FitVerdict::kAtNoiseFloor);
    }
    const SessionFit& base = bases.at(c.causality);
    daq::Session scaled = session;
    for (auto& e : scaled.experiments)
      for (auto& channel : e.channels)
        if (channel.name == c.channel)
          for (double& v : channel.samples) v *= 1.0 + c.gain;
    SessionFitOptions options = none;
    options.estimator.gain_sd = {{c.channel, c.gain}};
    const SessionFit with = FitPrepared(PrepareFitData(session, "drawn", model, options.estimator.n), model, options);
    const SessionFit moved = FitPrepared(PrepareFitData(scaled, "scaled", model, none.estimator.n), model, none);
    ASSERT_TRUE(moved.summary.converged);
    ASSERT_FALSE(with.summary.calibration.empty()) << "the gain is not covered";
    int compared = 0;
    for (int i : base.summary.estimated_positions) {
      const double shift = std::abs(moved.summary.parameters.value(i) - base.summary.parameters.value(i));
      const double predicted = with.summary.estimates[i].calibration_sd;
      const std::string key = base.summary.parameters.spec(i).key();
      // The sd with the calibration is the sd without it and the calibration part in quadrature.
      EXPECT_NEAR(with.summary.estimates[i].sd, std::hypot(base.summary.estimates[i].sd, predicted), 1e-6 * with.summary.estimates[i].sd) << key;
      if (shift < 0.05 * base.summary.estimates[i].sd) continue;  // below the fits' own convergence tolerance
      EXPECT_NEAR(shift / predicted, 1.0, 0.1) << key << " moved " << shift << ", predicted " << predicted;
      ++compared;
    }
    EXPECT_GE(compared, 3);
  }
}

TEST(SessionFit, WhatNoExperimentReachesIsFixedAndNamed) {
  // An end stop 30 mm outside the stroke the matrix uses: nothing in the data can size it.
  const daq::Session session = DrawnUnitSession(23);
  SessionFitOptions options;
  options.composition = "2dof+end-stop";
  options.assignments = "theta23=-0.03";
  const Model model = Model::Build(options.composition, options.causality);
  const FitData data = PrepareFitData(session, "drawn", model, options.estimator.n);
  const FitPlan plan = PlanFit(model, data, options);
  const int stiffness = plan.start.position("theta21"), position = plan.start.position("theta23");
  EXPECT_FALSE(plan.choices[stiffness].estimate && plan.choices[position].estimate);
  ASSERT_FALSE(plan.undetermined.empty());
  const std::string named = plan.undetermined.front();
  EXPECT_TRUE(named.find("theta21") != std::string::npos || named.find("theta23") != std::string::npos) << named;
  // The plan's log shows the values as used: theta23 from --set.
  bool logged = false;
  for (const std::string& line : plan.Describe())
    logged = logged || (line.find("theta23") != std::string::npos && line.find("-0.03") != std::string::npos &&
                        line.find("--set") != std::string::npos);
  EXPECT_TRUE(logged);
  // The paper's set on request.
  options.estimate = "paper";
  const FitPlan paper = PlanFit(model, data, options);
  int count = 0;
  for (const auto& c : paper.choices) count += c.estimate;
  EXPECT_EQ(count, 5);  // theta4, theta6, theta16, theta11, theta12
}

TEST(SessionFit, AnEndStopTheStartDoesNotReachIsEstimatedOnceTheFitReachesIt) {
  // Drawn unit 1005 of `bench units --effects-per-unit 3 --fit-truth`: its top-out stop lies inside
  // the matrix's stroke, but at the data's start (the stop at full extension) no experiment reaches
  // it, so the plan fixes its stiffness and position. The fit then bent the stroke zero to bring the
  // fixed stop to the contact the data show: theta12 3 mm off with an sd of 3 microns (z +1077).
  sim::UnitDraw draw;
  draw.effects = {{"end-stop", std::nullopt}, {"real-gas", std::nullopt}};
  const sim::SimulatedRig rig(sim::DrawUnit(sim::WithIdealRig(sim::DefaultTruth()), draw, 1005));
  sim::RigRunOptions run;
  run.seed = 1005;
  const daq::Session session = rig.RunMatrix(rig::StandardMatrixPlan(), run);
  const auto truth = sim::ReadRecordedTruth(session);
  ASSERT_TRUE(truth);
  SessionFitOptions options;
  options.composition = "2dof+end-stop+real-gas";
  const Model model = Model::Build(options.composition, options.causality);
  const FitData data = PrepareFitData(session, "drawn", model, options.estimator.n);
  const FitPlan plan = PlanFit(model, data, options);
  const int position = plan.start.position("theta23");
  ASSERT_NE(std::find(plan.undetermined_index.begin(), plan.undetermined_index.end(), position),
            plan.undetermined_index.end())
      << "the premise: the stop's position is out of the data's reach at the start";
  const SessionFit fit = FitPlanned(data, model, plan, options);
  ASSERT_EQ(fit.summary.Verdict(), FitVerdict::kAtNoiseFloor) << fit.summary.FullReport();
  EXPECT_TRUE(fit.plan.choices[position].estimate);
  for (const char* key : {"theta12", "theta23", "theta5", "theta6"}) {
    const int i = fit.summary.parameters.position(key);
    ASSERT_TRUE(fit.summary.estimates[i].estimated) << key;
    const double z = (fit.summary.parameters.value(i) - truth->parameters.get(key)) / fit.summary.estimates[i].sd;
    EXPECT_LT(std::abs(z), 3.5) << key << " estimate " << fit.summary.parameters.value(i) << " truth "
                                << truth->parameters.get(key) << " sd " << fit.summary.estimates[i].sd;
  }
  EXPECT_GT(fit.summary.estimates[fit.summary.parameters.position("theta12")].sd, 1e-4)
      << "the stroke zero's sd is the gas law's and its prior's, not the stop contact's";
}

TEST(SessionFit, ExcludeLeavesOutExperimentsAndChannelsAndNamesMistakes) {
  const daq::Session session = DrawnUnitSession(24);
  const Model model = Model::Build("2dof", Causality::kStrokeInput);
  const FitData data = PrepareFitData(session, "drawn", model, 800, {"a", "c:force"});
  EXPECT_EQ(data.experiments.size(), 13u);
  for (const auto& e : data.experiments) EXPECT_NE(e.label, "a");
  bool excluded = false;
  for (const auto& issue : data.issues) excluded = excluded || (issue.experiment == "c" && issue.channel == "force");
  EXPECT_TRUE(excluded);
  EXPECT_EQ(data.excluded.size(), 2u);
  try {
    PrepareFitData(session, "drawn", model, 800, {"zz"});
    FAIL() << "an exclusion that names nothing must be refused";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("zz"), std::string::npos) << e.what();
  }
}

TEST(SessionFit, AnExperimentWithoutWholeSamplesPerPeriodKeepsEightHundredPoints) {
  // Another tool's record at 0.3003 Hz and 200 Hz, 666.0007 samples a period: it is resampled onto
  // an equidistant grid, 800 points by default (as before the thinned grid), while 0.1 Hz (2000
  // samples) is thinned. (The simulated rig records whole periods only: the copy of b is relabelled.)
  rig::MatrixPlan plan;
  plan.experiments = {{"b", "middle", 0.1, 0.133, 0.127}};
  const sim::SimulatedRig rig(DrawnIdealUnit(26));
  daq::Session session = rig.RunMatrix(plan);
  ASSERT_EQ(session.experiments.size(), 1u);
  daq::Experiment copy = session.experiments[0];
  copy.label = "x";
  copy.frequency = 0.3003;
  session.experiments.push_back(copy);
  const Model model = Model::Build("2dof", Causality::kStrokeInput);
  const FitData data = PrepareFitData(session, "drawn", model, 0);
  ASSERT_EQ(data.experiments.size(), 2u);
  const ExperimentData& b = data.experiments[0];
  const ExperimentData& x = data.experiments[1];
  EXPECT_EQ(b.phases.size(), 2000u);
  EXPECT_LT(b.input.values.size(), 1000u);
  EXPECT_FALSE(b.input.phases.empty());
  EXPECT_EQ(x.phases.size(), 800u);
  EXPECT_EQ(x.input.values.size(), 800u);
  EXPECT_TRUE(x.input.phases.empty());
  // An explicit --n is what it says.
  EXPECT_EQ(PrepareFitData(session, "drawn", model, 300).experiments[1].input.values.size(), 300u);
}

TEST(SessionFit, AFitStoppedBeforeItConvergedSaysSoAndWhatToTry) {
  // One iteration from 20 % off cannot converge: the verdict (identify's exit code 2) says so.
  const daq::Session session = DrawnUnitSession(25);
  SessionFitOptions options;
  options.estimator.max_iterations = 1;
  options.assignments = "theta4=0.006,theta15=22";
  const Model model = Model::Build(options.composition, options.causality);
  const FitData data = PrepareFitData(session, "drawn", model, options.estimator.n);
  const FitSummary fit = Estimator(model, options.estimator)
                             .Fit(data.experiments, PlanFit(model, data, options).start,
                                  DefaultChoices(model), data.issues);
  EXPECT_FALSE(fit.converged);
  EXPECT_EQ(fit.Verdict(), FitVerdict::kNotConverged);
  EXPECT_NE(fit.VerdictText().find("NOT CONVERGED"), std::string::npos) << fit.VerdictText();
  EXPECT_NE(fit.VerdictText().find("--params"), std::string::npos);
}

}  // namespace
}  // namespace strut::ident
