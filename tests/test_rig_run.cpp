// The matrix runner (rig/matrix_runner.h, docs/rig-run.md) on a small deterministic plant
// (tests/support/rig_plant.h: stroke follows the command, force a known function of stroke and
// velocity) behind the device interfaces, in-process and over the real Modbus TCP client and
// server: ramps, whole periods in steady state, the not-steady time-out, every detector with its
// action, device losses, sequence gaps, a refused command, pause and resume. Each fault ends with
// the controller safe, the data kept and the cause recorded as an event.
#include <gtest/gtest.h>
#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <numbers>
#include <optional>
#include <set>

#include "rig_plant.h"
#include "session_events.h"
#include "strut/daq/modbus_controller.h"
#include "strut/daq/recorder.h"
#include "strut/daq/session.h"
#include "strut/rig/matrix_runner.h"
#include "test_support.h"

namespace strut::rig {
namespace {

using test::DirectController;
using test::Plant;
using test::PlantAcquisition;
using test::PlantOptions;
using test::TempDir;

// The first event of `kind` whose text contains `part`, or "".
std::string FindEvent(const daq::Session& s, const std::string& kind, const std::string& part = "") {
  for (const auto& [k, text] : test::SessionEvents(s))
    if (k == kind && text.find(part) != std::string::npos) return text;
  return "";
}

std::string AllEvents(const daq::Session& s) {
  std::string out;
  for (const auto& [k, text] : test::SessionEvents(s)) out += k + ": " + text + "\n";
  return out;
}

bool Contains(const std::vector<daq::ControllerCommand>& v, daq::ControllerCommand c) {
  return std::find(v.begin(), v.end(), c) != v.end();
}

// Short experiments at 10 Hz sampled at 1 kHz (100 samples a period): about a second each.
MatrixEntry Entry(const std::string& label, double static_position = 0.12, double amplitude = 0.01,
                  double frequency = 10.0) {
  return {label, "middle", frequency, static_position, amplitude};
}

struct Bench {
  explicit Bench(PlantOptions o = {}) : plant(o), controller(plant), acquisition(plant) {
    options.periods = 2;
    options.ramp_cycles = 1;
    options.static_rate = 0.5;
    options.steady.max_cycles = 8;
    options.steady.drift_window = 0.0;  // the plant has no thermal drift; the runs are in real time
    options.settle_margin = std::chrono::milliseconds(3000);
    safety.stale.timeout = std::chrono::milliseconds(400);
  }

  // Runs the entries into a new session and returns it as written.
  daq::Session Run(const std::vector<MatrixEntry>& matrix, std::function<void(const Progress&, MatrixRunner&)> hook = {}) {
    std::vector<RunItem> items;
    for (const MatrixEntry& e : matrix) items.push_back({e});
    daq::RecordingMetadata m;
    m.damper_serial = "T-1";
    m.rig = "plant";
    auto recorder = daq::Recorder::Open(path(), m);
    report = RunOn(recorder, items, hook);
    recorder.Close(report.outcome != RunOutcome::kComplete);
    return daq::ReadSession(path());
  }
  RunReport RunOn(daq::Recorder& recorder, const std::vector<RunItem>& items,
                  std::function<void(const Progress&, MatrixRunner&)> hook = {}) {
    MatrixRunner runner(controller, acquisition, recorder, safety, options);
    runner.on_progress = [&](const Progress& p) {
      progress.push_back(p);
      if (hook) hook(p, runner);
    };
    return runner.Run(items);
  }
  std::string path() const { return dir.file("s.h5"); }

  Plant plant;
  DirectController controller;
  PlantAcquisition acquisition;
  TempDir dir;
  SafetyConfig safety;
  RunnerOptions options;
  RunReport report;
  std::vector<Progress> progress;
};

// Calls `inject` once, the first time the runner is in `phase` of experiment `label`.
std::function<void(const Progress&, MatrixRunner&)> Once(RunPhase phase, std::function<void()> inject,
                                                         std::string label = "") {
  auto done = std::make_shared<bool>(false);
  return [=](const Progress& p, MatrixRunner&) {
    if (!*done && p.phase == phase && (label.empty() || p.experiment == label)) {
      *done = true;
      inject();
    }
  };
}

// Calls `inject` once, when at least one period of the record is in (records of 4 periods).
std::function<void(const Progress&, MatrixRunner&)> InRecord(std::function<void()> inject, std::string label = "") {
  auto done = std::make_shared<bool>(false);
  return [=](const Progress& p, MatrixRunner&) {
    if (!*done && p.phase == RunPhase::kRecording && p.periods_recorded >= 1 && (label.empty() || p.experiment == label)) {
      *done = true;
      inject();
    }
  };
}

TEST(MatrixRunner, RecordsTheRequestedWholePeriodsOfEachExperimentInSteadyState) {
  Bench b;
  const daq::Session s = b.Run({Entry("a", 0.12, 0.01), Entry("b", 0.15, 0.02, 5.0)});
  ASSERT_EQ(b.report.outcome, RunOutcome::kComplete) << b.report.cause;
  EXPECT_EQ(b.report.complete, (std::vector<std::string>{"a", "b"}));
  EXPECT_TRUE(b.report.disarmed);
  ASSERT_EQ(s.experiments.size(), 2u);
  EXPECT_TRUE(daq::Validate(s).empty());
  // Each experiment says when its recording began: ISO 8601 UTC, in recording order, no earlier
  // than the session's creation.
  std::string previous = s.created_utc;
  for (const daq::Experiment& e : s.experiments) {
    const std::string& started = e.extra_attributes.at("started_utc");
    EXPECT_EQ(started.size(), 20u) << started;
    EXPECT_EQ(started.back(), 'Z') << started;
    EXPECT_GE(started, previous) << e.label;
    previous = started;
  }
  for (const daq::Experiment& e : s.experiments) {
    SCOPED_TRACE(e.label);
    EXPECT_EQ(e.status, "complete");
    EXPECT_EQ(e.extra_attributes.at("recording_end"), "complete");
    EXPECT_EQ(e.periods, 2);
    EXPECT_DOUBLE_EQ(e.sample_rate, 1000.0);
    EXPECT_EQ(e.sample_count(), static_cast<std::size_t>(2 * 1000.0 / e.frequency));
    // Steady state: the recorded stroke swings the commanded amplitude about the static position
    // (16-bit counts over 0.31 m: 4.7 um a count).
    const auto& stroke = e.channel("stroke").samples;
    const auto [lo, hi] = std::minmax_element(stroke.begin(), stroke.end());
    EXPECT_NEAR(0.5 * (*hi - *lo), e.amplitude, 1e-5);
    EXPECT_NEAR(0.5 * (*hi + *lo), e.static_position, 1e-5);
    // The force is the plant's known function of stroke and velocity (backward differences of the
    // recorded stroke; counts of 1.8 N and 4.7 um x 4 kN s/m / 1 ms: 20 N at worst).
    const auto& force = e.channel("force").samples;
    for (std::size_t i = 1; i < stroke.size(); i += 7) {
      const double v = (stroke[i] - stroke[i - 1]) * 1000.0;  // the plant's own backward difference
      EXPECT_NEAR(force[i], b.plant.ForceOf(stroke[i], v, 0.0), 25.0) << "sample " << i;
    }
    // The cycle summaries are in the session, and re-running the detector on them agrees.
    const daq::MetadataGroup* cycles = s.find_metadata("rig_run")->find_group(e.label);
    ASSERT_NE(cycles, nullptr);
    const auto summaries = CyclesFromGroup(*cycles);
    const SteadyStateVerdict v = DetectSteadyState(summaries, TolerancesFromGroup(*cycles));
    EXPECT_TRUE(v.steady);
    EXPECT_EQ(v.steady_at, *cycles->number("steady_at"));
    EXPECT_EQ(*cycles->number("first_recorded_cycle"), v.steady_at + 1);
    // ... and so does the detector on the recorded periods themselves.
    const auto recorded = SummariseExperiment(e);
    ASSERT_EQ(recorded.size(), 2u);
    EXPECT_LT(ChangeBetween(recorded[0], recorded[1], SteadyStateTolerances{}).worst_ratio(SteadyStateTolerances{}), 1.0);
  }
  EXPECT_NE(FindEvent(s, "complete"), "");
  // The progress display saw every phase.
  std::set<RunPhase> phases;
  for (const Progress& p : b.progress) phases.insert(p.phase);
  for (RunPhase p : {RunPhase::kMoving, RunPhase::kRampIn, RunPhase::kSettling, RunPhase::kRecording, RunPhase::kRampOut})
    EXPECT_TRUE(phases.count(p)) << ToString(p);
  // ... and, in every phase of an experiment, the periods it records.
  for (const Progress& p : b.progress)
    if (!p.experiment.empty()) EXPECT_EQ(p.periods_requested, b.options.periods) << p.experiment << " " << ToString(p.phase);
  // Our heartbeat every loop, the watchdog set at the start and off at the end.
  EXPECT_GT(b.controller.beats.load(), 50);
  EXPECT_EQ(b.controller.watchdogs.front(), 1000);
  EXPECT_EQ(b.controller.watchdogs.back(), 0);
}

TEST(MatrixRunner, MovesAtTheRateLimitWithoutSineAndRampsInAndOutOverWholeCycles) {
  Bench b;
  b.options.static_rate = 0.1;
  b.options.ramp_cycles = 2;
  const daq::Session s = b.Run({Entry("a", 0.16, 0.01), Entry("b", 0.10, 0.01)});
  ASSERT_EQ(b.report.outcome, RunOutcome::kComplete) << b.report.cause;
  // Every set-point that changes the static position has no amplitude and the rate limit.
  double last_static = 0.1;
  for (const daq::SetPoint& sp : b.plant.applied()) {
    if (sp.static_position != last_static) {
      EXPECT_EQ(sp.amplitude, 0.0);
      EXPECT_EQ(sp.ramp_cycles, 2);
    }
    EXPECT_DOUBLE_EQ(sp.static_rate, 0.1);
    last_static = sp.static_position;
  }
  // Sine started only at the static level, the ramp took two whole cycles, and the stroke moved no
  // faster than 0.1 m/s while armed (moves between static levels).
  const auto h = b.plant.history();
  int runs = 0;
  for (std::size_t i = 1; i < h.size(); ++i) {
    if (h[i].state == daq::ControllerState::kArmed && h[i - 1].state == daq::ControllerState::kArmed) {
      EXPECT_LE(std::abs(h[i].stroke - h[i - 1].stroke) * 1000.0, 0.1 + 1e-9) << "sample " << i;
    }
    if (h[i].state == daq::ControllerState::kRunning && h[i - 1].state == daq::ControllerState::kArmed) {
      ++runs;
      EXPECT_NEAR(h[i].command, h[i - 1].command, 0.01 * 2 * std::numbers::pi / 100 + 1e-12);  // starts at the mean
      // Full amplitude after 2 cycles (200 samples), not before.
      EXPECT_LT(h[i + 150].amplitude, 0.01);
      EXPECT_DOUBLE_EQ(h[i + 200].amplitude, 0.01);
    }
  }
  EXPECT_EQ(runs, 2);
}

TEST(MatrixRunner, AResponseThatNeverSettlesIsRecordedAnywayAndMarkedNotSteady) {
  PlantOptions o;
  o.force_drift = 2.0e4;  // N/s: 2 kN a cycle on a 4 kN swing
  Bench b(o);
  b.safety.force.enabled = false;
  b.options.steady.max_cycles = 5;
  const daq::Session s = b.Run({Entry("a")});
  ASSERT_EQ(b.report.outcome, RunOutcome::kComplete) << b.report.cause;
  EXPECT_EQ(b.report.not_steady, std::vector<std::string>{"a"});
  ASSERT_EQ(s.experiments.size(), 1u);
  const daq::Experiment& e = s.experiments[0];
  EXPECT_EQ(e.status, "complete");
  EXPECT_EQ(e.extra_attributes.at("recording_end"), "not-steady");
  EXPECT_EQ(e.sample_count(), 200u);
  const daq::MetadataGroup* cycles = s.find_metadata("rig_run")->find_group("a");
  EXPECT_EQ(*cycles->number("timed_out"), 1.0);
  EXPECT_EQ(*cycles->number("first_recorded_cycle"), 5.0);
  EXPECT_NE(FindEvent(s, "not-steady", "'a'"), "");
}

TEST(MatrixRunner, AStrokeLimitTripMidSineInterlocksAndKeepsTheData) {
  // Trip while recording 'a': a stroke offset of 9 cm pushes it over 0.20 m.
  Bench c;
  c.options.periods = 4;
  c.safety.stroke.upper = 0.20;
  const daq::Session t = c.Run({Entry("a"), Entry("b")}, InRecord([&] { c.plant.SetStrokeOffset(0.09); }));
  ASSERT_EQ(c.report.outcome, RunOutcome::kAborted);
  ASSERT_TRUE(c.report.trip);
  EXPECT_EQ(c.report.trip->detector, "stroke-limit");
  EXPECT_EQ(c.report.trip->action, SafetyAction::kInterlock);
  // Interlock: disarmed at once, without waiting for a ramp out.
  const auto commands = c.plant.commands();
  EXPECT_TRUE(Contains(commands, daq::ControllerCommand::kDisarm));
  EXPECT_FALSE(Contains(commands, daq::ControllerCommand::kStop));
  EXPECT_TRUE(c.report.disarmed);
  ASSERT_EQ(t.experiments.size(), 1u);
  EXPECT_EQ(t.experiments[0].status, "aborted");
  // The samples up to and including those beyond the limit are kept.
  const auto& stroke = t.experiments[0].channel("stroke").samples;
  EXPECT_GE(stroke.size(), 100u);
  EXPECT_GT(*std::max_element(stroke.begin(), stroke.end()), 0.20);
  EXPECT_EQ(c.report.remaining, (std::vector<std::string>{"a", "b"}));
  EXPECT_NE(FindEvent(t, "trip", "stroke-limit: stroke"), "") << AllEvents(t);
  EXPECT_NE(FindEvent(t, "aborted", "remaining: a b"), "") << AllEvents(t);
  // The journal is kept for a resume.
  EXPECT_TRUE(std::filesystem::exists(daq::JournalPath(c.path())));
}

TEST(MatrixRunner, AFollowingErrorStopsWithARampOutToStaticThenDisarms) {
  Bench b;
  const daq::Session s = b.Run({Entry("a")}, Once(RunPhase::kSettling, [&] { b.plant.SetStrokeOffset(0.015); }));
  ASSERT_EQ(b.report.outcome, RunOutcome::kAborted);
  EXPECT_EQ(b.report.trip->detector, "following-error");
  EXPECT_EQ(b.report.trip->action, SafetyAction::kStop);
  const auto commands = b.plant.commands();
  const auto stop = std::find(commands.begin(), commands.end(), daq::ControllerCommand::kStop);
  const auto disarm = std::find(commands.begin(), commands.end(), daq::ControllerCommand::kDisarm);
  ASSERT_NE(stop, commands.end());
  ASSERT_NE(disarm, commands.end());
  EXPECT_LT(stop - commands.begin(), disarm - commands.begin());
  // The ramp out ran and ended at the static level before hydraulics went off (the plant's last
  // sample before the disarm).
  const auto h = b.plant.history();
  EXPECT_TRUE(std::any_of(h.begin(), h.end(), [](const auto& x) { return x.state == daq::ControllerState::kStopping; }));
  EXPECT_EQ(h.back().state, daq::ControllerState::kArmed);
  EXPECT_EQ(h.back().amplitude, 0.0);
  EXPECT_NEAR(h.back().stroke, 0.12 + 0.015, 1e-12);
  EXPECT_NE(FindEvent(s, "trip", "following-error"), "") << AllEvents(s);
  // Nothing was being recorded yet: no experiment in the session, the cause is there.
  EXPECT_TRUE(s.experiments.empty());
}

TEST(MatrixRunner, AnIndicateLimitOnlyRecordsAnEventAndTheRunGoesOn) {
  Bench b;
  b.safety.force = {true, -1000.0, 2500.0, 2, SafetyAction::kIndicate};  // the force swings between about 2 and 8 kN
  const daq::Session s = b.Run({Entry("a")});
  EXPECT_EQ(b.report.outcome, RunOutcome::kComplete) << b.report.cause;
  EXPECT_NE(FindEvent(s, "trip", "force-limit: force"), "") << AllEvents(s);
  EXPECT_NE(FindEvent(s, "trip", "(action indicate)"), "");
}

TEST(MatrixRunner, UnderPeakWithHoldPausesTheRunResumably) {
  Bench b;
  b.safety.under_peak.action = SafetyAction::kHold;
  const daq::Session s = b.Run({Entry("a"), Entry("b")}, Once(RunPhase::kSettling, [&] { b.plant.SetTracking(0.5); }));
  ASSERT_EQ(b.report.outcome, RunOutcome::kPaused) << b.report.cause;
  EXPECT_EQ(b.report.trip->detector, "under-peak");
  EXPECT_NE(b.report.trip->text.find("50.0 %"), std::string::npos) << b.report.trip->text;
  EXPECT_TRUE(Contains(b.plant.commands(), daq::ControllerCommand::kStop));
  EXPECT_TRUE(b.report.disarmed);
  EXPECT_NE(FindEvent(s, "trip", "under-peak"), "") << AllEvents(s);
  EXPECT_NE(FindEvent(s, "paused"), "");
}

TEST(MatrixRunner, AStreamLateByMoreThanTheRampIsNotJudgedUnderPeakOnTheRampsSamples) {
  // Every sample arrives 600 ms after its time: six 10 Hz cycles, while the ramp in is one. When
  // the controller reports full amplitude the stream still holds the ramp and the slow move to the
  // static position before it, which are not full-amplitude cycles (they tripped under-peak:
  // 3 cycles below 80 %).
  Bench b;
  b.options.static_rate = 0.02;  // the 20 mm move to the static position takes 10 cycles' time
  b.acquisition.delay_ns = 600'000'000;
  b.safety.lag.max_lag = std::chrono::milliseconds(2000);  // late by design here, not a lagging module
  b.safety.stale.timeout = std::chrono::milliseconds(1500);  // the first sample comes 600 ms after the start
  const daq::Session s = b.Run({Entry("a", 0.12)});
  EXPECT_EQ(b.report.outcome, RunOutcome::kComplete) << b.report.cause << "\n" << AllEvents(s);
  EXPECT_EQ(FindEvent(s, "trip"), "") << AllEvents(s);
  ASSERT_EQ(s.experiments.size(), 1u);
  const std::vector<double>& stroke = s.experiments[0].channel("stroke").samples;
  const auto [lo, hi] = std::minmax_element(stroke.begin(), stroke.end());
  EXPECT_NEAR(0.5 * (*hi - *lo), 0.01, 2e-4);  // the record is at full amplitude
}

TEST(MatrixRunner, ALostControllerEndsTheRunWithTheRecordKeptAndTheCause) {
  Bench b;
  b.options.periods = 6;
  b.options.controller_grace = std::chrono::milliseconds(200);
  const daq::Session s = b.Run({Entry("a"), Entry("b")}, InRecord([&] { b.controller.fail = true; }));
  ASSERT_EQ(b.report.outcome, RunOutcome::kAborted);
  EXPECT_EQ(b.report.trip->detector, "controller-lost");
  EXPECT_NE(b.report.trip->text.find("Connection reset by peer"), std::string::npos);
  ASSERT_EQ(s.experiments.size(), 1u);
  EXPECT_EQ(s.experiments[0].status, "aborted");
  EXPECT_GT(s.experiments[0].sample_count(), 200u);  // the grace period kept recording
  EXPECT_NE(FindEvent(s, "trip", "controller-lost"), "") << AllEvents(s);
  EXPECT_FALSE(b.report.disarmed);  // nothing to command: the controller's watchdog stops it
}

TEST(MatrixRunner, AFrozenAcquisitionTripsStaleDataAndStopsSafely) {
  Bench b;
  b.options.periods = 4;
  const daq::Session s = b.Run({Entry("a")}, InRecord([&] { b.acquisition.freeze = true; }));
  ASSERT_EQ(b.report.outcome, RunOutcome::kAborted);
  EXPECT_EQ(b.report.trip->detector, "stale-data");
  EXPECT_TRUE(Contains(b.plant.commands(), daq::ControllerCommand::kStop));
  EXPECT_TRUE(b.report.disarmed);
  ASSERT_EQ(s.experiments.size(), 1u);
  EXPECT_EQ(s.experiments[0].status, "aborted");
  EXPECT_GE(s.experiments[0].sample_count(), 100u);
  EXPECT_NE(FindEvent(s, "stale"), "") << AllEvents(s);  // the acquisition's own event
  EXPECT_NE(FindEvent(s, "trip", "stale-data: no sample"), "") << AllEvents(s);
}

TEST(MatrixRunner, ALostAcquisitionStreamStopsSafely) {
  Bench b;
  const daq::Session s = b.Run({Entry("a")}, Once(RunPhase::kSettling, [&] { b.acquisition.fail = true; }));
  ASSERT_EQ(b.report.outcome, RunOutcome::kAborted);
  EXPECT_EQ(b.report.trip->detector, "acquisition-lost");
  EXPECT_NE(b.report.trip->text.find("Input/output error"), std::string::npos);
  EXPECT_TRUE(Contains(b.plant.commands(), daq::ControllerCommand::kStop));
  EXPECT_TRUE(b.report.disarmed);
  EXPECT_NE(FindEvent(s, "trip", "acquisition-lost"), "") << AllEvents(s);
}

TEST(MatrixRunner, ASequenceGapInTheRecordAbortsItAndTheExperimentIsRecordedAgain) {
  Bench b;
  b.options.periods = 4;
  const daq::Session s = b.Run({Entry("a"), Entry("b")}, InRecord([&] { b.acquisition.Gap(37); }, "a"));
  ASSERT_EQ(b.report.outcome, RunOutcome::kComplete) << b.report.cause;
  ASSERT_EQ(s.experiments.size(), 3u);
  EXPECT_EQ(s.experiments[0].label, "a");
  EXPECT_EQ(s.experiments[0].status, "aborted");
  EXPECT_EQ(s.experiments[1].label, "a-2");
  EXPECT_EQ(s.experiments[1].status, "complete");
  EXPECT_EQ(s.experiments[1].extra_attributes.at("matrix_label"), "a");
  EXPECT_EQ(s.experiments[1].sample_count(), 400u);
  EXPECT_GE(s.experiments[0].sample_count(), 100u);
  EXPECT_EQ(s.experiments[2].label, "b");
  // No sample set is missing inside a complete record: the sequence counts up by one.
  const auto& seq = s.experiments[1].channel("sequence").samples;
  for (std::size_t i = 1; i < seq.size(); ++i) ASSERT_EQ(seq[i], seq[i - 1] + 1);
  EXPECT_NE(FindEvent(s, "sequence-gap", "37"), "") << AllEvents(s);
  EXPECT_NE(FindEvent(s, "abort", "experiment 'a': 37 sample sets lost"), "") << AllEvents(s);
}

TEST(MatrixRunner, AnOutOfRangeCommandIsRefusedBeforeTheActuatorMoves) {
  Bench b;
  // Beyond the controller's stroke limit (0.36 m): the set-point is refused by the client's check.
  const daq::Session s = b.Run({Entry("a", 0.40, 0.01)});
  ASSERT_EQ(b.report.outcome, RunOutcome::kAborted);
  EXPECT_EQ(b.report.trip->detector, "controller-refused");
  EXPECT_NE(b.report.trip->text.find("set-point (static position)"), std::string::npos) << b.report.trip->text;
  EXPECT_TRUE(b.plant.applied().empty());
  for (const auto& sample : b.plant.history()) ASSERT_DOUBLE_EQ(sample.stroke, 0.1);
  EXPECT_NE(FindEvent(s, "trip", "controller-refused"), "") << AllEvents(s);
}

TEST(MatrixRunner, AFrozenControllerHeartbeatInterlocks) {
  Bench b;
  b.safety.heartbeat.controller_timeout = std::chrono::milliseconds(300);
  const daq::Session s = b.Run({Entry("a")}, Once(RunPhase::kSettling, [&] { b.controller.freeze_heartbeat = true; }));
  ASSERT_EQ(b.report.outcome, RunOutcome::kAborted);
  EXPECT_EQ(b.report.trip->detector, "controller-heartbeat");
  EXPECT_TRUE(Contains(b.plant.commands(), daq::ControllerCommand::kDisarm));
  EXPECT_NE(FindEvent(s, "trip", "heartbeat counter stayed"), "") << AllEvents(s);
}

TEST(MatrixRunner, AControllerWithALatchedFaultIsNotMoved) {
  Bench b;
  b.plant.InjectFault(daq::fault_bits::kHydraulics);
  const daq::Session s = b.Run({Entry("a")});
  ASSERT_EQ(b.report.outcome, RunOutcome::kAborted);
  EXPECT_EQ(b.report.trip->detector, "controller-fault");
  EXPECT_NE(b.report.cause.find("reset them first"), std::string::npos);
  EXPECT_TRUE(b.plant.applied().empty());
  EXPECT_NE(FindEvent(s, "trip", "hydraulics"), "") << AllEvents(s);
}

TEST(MatrixRunner, PausesAtTheExperimentBoundaryAndAResumeCompletesTheMatrixInTheSameFile) {
  Bench b;
  const std::vector<MatrixEntry> matrix{Entry("a"), Entry("b", 0.14), Entry("c", 0.1, 0.005)};
  const daq::Session paused =
      b.Run(matrix, [](const Progress& p, MatrixRunner& r) { if (p.phase == RunPhase::kSettling) r.RequestPause(); });
  ASSERT_EQ(b.report.outcome, RunOutcome::kPaused) << b.report.cause;
  EXPECT_EQ(b.report.complete, std::vector<std::string>{"a"});
  EXPECT_EQ(b.report.remaining, (std::vector<std::string>{"b", "c"}));
  ASSERT_EQ(paused.experiments.size(), 1u);
  EXPECT_NE(FindEvent(paused, "pause", "before experiment 'b'"), "") << AllEvents(paused);
  // Resume: the same file, only what is left.
  daq::Session so_far;
  auto recorder = daq::Recorder::Resume(b.path(), {}, "resumed by the test", &so_far);
  const std::vector<RunItem> rest = RemainingExperiments(matrix, so_far);
  ASSERT_EQ(rest.size(), 2u);
  EXPECT_EQ(rest[0].label(), "b");
  const RunReport r = b.RunOn(recorder, rest);
  recorder.Close();
  ASSERT_EQ(r.outcome, RunOutcome::kComplete) << r.cause;
  const daq::Session s = daq::ReadSession(b.path());
  ASSERT_EQ(s.experiments.size(), 3u);
  for (const auto& e : s.experiments) EXPECT_EQ(e.status, "complete") << e.label;
  EXPECT_EQ(s.experiments[0].channel("stroke").samples, paused.experiments[0].channel("stroke").samples);
  EXPECT_NE(FindEvent(s, "resumed", "resumed by the test"), "");
  EXPECT_FALSE(std::filesystem::exists(daq::JournalPath(b.path())));
  // Everything complete: nothing left to run.
  EXPECT_TRUE(RemainingExperiments(matrix, s).empty());
}

TEST(MatrixRunner, AStopRequestRampsOutAndLeavesTheRunResumable) {
  Bench b;
  b.options.periods = 4;
  const daq::Session s = b.Run({Entry("a"), Entry("b")}, [](const Progress& p, MatrixRunner& r) {
    if (p.phase == RunPhase::kRecording && p.periods_recorded >= 1) r.RequestStop();
  });
  ASSERT_EQ(b.report.outcome, RunOutcome::kPaused);
  EXPECT_EQ(b.report.trip->detector, "operator-stop");
  ASSERT_EQ(s.experiments.size(), 1u);
  EXPECT_EQ(s.experiments[0].status, "aborted");
  const auto items = RemainingExperiments({Entry("a"), Entry("b")}, s);
  ASSERT_EQ(items.size(), 2u);
  EXPECT_EQ(items[0].label(), "a-2");  // the aborted record keeps its label
  EXPECT_NE(FindEvent(s, "stop", "operator"), "") << AllEvents(s);
}

// A device lost while the run is already going safe is a trip like any other then (Handle): noted
// as such, the first cause stays the run's.
TEST(MatrixRunner, AStreamLostWhileSafingIsNotedAndTheFirstCauseStays) {
  Bench b;
  b.options.periods = 4;
  bool stopped = false;
  const daq::Session s = b.Run({Entry("a")}, [&](const Progress& p, MatrixRunner& r) {
    if (!stopped && p.phase == RunPhase::kRecording && p.periods_recorded >= 1) stopped = true, r.RequestStop();
    if (p.phase == RunPhase::kSafing) b.acquisition.fail = true;
  });
  ASSERT_EQ(b.report.outcome, RunOutcome::kPaused);
  EXPECT_EQ(b.report.trip->detector, "operator-stop");
  EXPECT_TRUE(b.report.disarmed);
  const std::string lost = FindEvent(s, "trip", "acquisition-lost: the acquisition stream failed");
  EXPECT_NE(lost.find("(while safing after an earlier trip)"), std::string::npos) << AllEvents(s);
}

TEST(MatrixRunner, OverModbusTcpRecordsAndALostServerEndsTheRunSafely) {
  Bench b;
  daq::ModbusControllerServer server(b.plant);
  daq::ModbusControllerOptions o;
  o.endpoint = server.endpoint();
  o.response_timeout = std::chrono::milliseconds(200);
  o.reconnect_initial = std::chrono::milliseconds(50);
  daq::ModbusController modbus(o);
  b.options.controller_grace = std::chrono::milliseconds(300);
  b.options.periods = 6;
  std::vector<RunItem> items{{Entry("a")}, {Entry("b", 0.14)}};
  daq::RecordingMetadata m;
  m.damper_serial = "T-1";
  m.rig = "plant over modbus";
  auto recorder = daq::Recorder::Open(b.path(), m);
  MatrixRunner runner(modbus, b.acquisition, recorder, b.safety, b.options);
  bool stopped = false;
  runner.on_progress = [&](const Progress& p) {
    if (!stopped && p.experiment == "b" && p.phase == RunPhase::kRecording && p.periods_recorded >= 1) {
      stopped = true;
      server.Stop();
    }
  };
  const RunReport r = runner.Run(items);
  recorder.Close(true);
  ASSERT_EQ(r.outcome, RunOutcome::kAborted) << r.cause;
  EXPECT_EQ(r.trip->detector, "controller-lost");
  EXPECT_EQ(r.complete, std::vector<std::string>{"a"});
  const daq::Session s = daq::ReadSession(b.path());
  ASSERT_GE(s.experiments.size(), 1u);
  EXPECT_EQ(s.experiments[0].status, "complete");
  EXPECT_EQ(s.experiments[0].sample_count(), 600u);
  ASSERT_EQ(s.experiments.size(), 2u);
  EXPECT_EQ(s.experiments[1].status, "aborted");
  EXPECT_NE(FindEvent(s, "trip", "controller-lost"), "") << AllEvents(s);
}

}  // namespace
}  // namespace strut::rig
