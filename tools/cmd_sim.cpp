// strut sim: the simulated rig. `sim matrix` runs a test matrix (the standard one by default) and
// writes a contract-format session of whole steady-state periods; `sim drop` writes a drop test;
// `sim truth` shows (or writes out) the truth the rig simulates. docs/simulated-rig.md.
#include <spdlog/spdlog.h>

#include <chrono>
#include <cstdint>
#include <optional>
#include <fstream>
#include <iostream>

#include "commands.h"
#include "sim_commands.h"
#include "option_checks.h"
#include "output_files.h"
#include "truth_options.h"
#include "strut/daq/session.h"
#include "strut/sim/simulated_rig.h"
#include "strut/sim/truth.h"

namespace strut::tools {
namespace {

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

std::string RangeText(const std::vector<double>& v, double scale) {
  const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
  return fmt::format("{:8.3f}..{:8.3f}", *lo * scale, *hi * scale);
}

struct SimTruthCommand {
  TruthOptions truth;
  std::string write_path;

  void Run() const {
    if (!write_path.empty()) {
      CheckOutputPath("--write-default", write_path, {truth.truth_path});
      WriteTextOutput(write_path, std::string(sim::DefaultTruthText()));
      return;
    }
    const sim::SimulatedRig rig(truth.Load());
    const sim::Truth& t = rig.truth();
    std::cout << fmt::format("truth: {}\ndamper: {}\nmodel: {}\neffects:", t.source, t.damper_serial,
                             rig.model().composition());
    for (const auto& e : sim::Truth::EffectNames()) std::cout << fmt::format(" {}={}", e, t.has_effect(e) ? "on" : "off");
    if (t.drawn) {
      std::cout << fmt::format("\ndrawn: seed {}, base {}, around {}, feasible after {} candidate(s)", t.drawn->seed,
                               t.drawn->base, t.drawn->around, t.drawn->attempts);
      for (const sim::EffectSize& e : t.drawn->effects)
        std::cout << fmt::format("\n  effect {}: {} = {:.6g} ({})", e.effect, e.parameter, e.size,
                                 e.given ? "given" : "drawn");
    }
    std::cout << "\nparameters:\n" << rig.truth().RecordedParameters(rig.model()).table() << "\n";
    const sim::ActuatorOptions& a = t.actuator;
    if (a.ideal)
      std::cout << "actuator: ideal (the stroke follows the set-point)\n";
    else
      std::cout << fmt::format(
          "actuator: loop {} Hz, feed-forward {}, valve {} Hz, max velocity {} m/s, stall force {} kN, force limit {} kN, "
          "control {} Hz\n",
          a.loop_bandwidth, a.feedforward, a.valve_bandwidth, a.max_velocity, a.stall_force * 1e-3, a.force_limit * 1e-3,
          a.control_rate);
    for (const auto& [name, s] : {std::pair{"stroke", &t.sensors.stroke}, std::pair{"force", &t.sensors.force},
                                  std::pair{"pressure", &t.sensors.pressure}})
      std::cout << fmt::format("sensor {:<8}: range [{}, {}] {}, noise {}, offset {}, gain error {}, {} bits (LSB {:.3g})\n",
                               name, s->range_min, s->range_max, s->units, s->noise, s->offset, s->gain_error, s->bits,
                               s->lsb());
    std::cout << fmt::format("acquisition: {} Hz periodic, {} Hz drop, {} periods, settle to {:.0e} within {} periods, "
                             "{} pressure\nfaults: {}\n",
                             t.acquisition.sample_rate, t.acquisition.drop_sample_rate, t.acquisition.periods,
                             t.acquisition.settle_tolerance, t.acquisition.settle_periods_max,
                             t.acquisition.gauge_pressure ? "gauge" : "absolute", t.faults.size());
  }
};

}  // namespace

void RunOptions::Add(CLI::App& command) {
  command.add_option("--seed", seed, "The seed of the noise, start phases and faults: the same seed gives the same session.")
      ->capture_default_str();
  command.add_flag("--real-time", real_time, "Pace the simulation to the wall clock, as a real rig delivers samples.");
  command.add_option("--speed", speed, "With --real-time: simulated seconds per wall second.")
      ->check(Positive())
      ->capture_default_str();
}

sim::RigRunOptions RunOptions::Get() const {
  sim::RigRunOptions o;
  o.seed = seed;
  o.clock.mode = real_time ? sim::ClockMode::kRealTime : sim::ClockMode::kFast;
  o.clock.speed = speed;
  return o;
}

daq::Session SimMatrixCommand::Record(std::vector<sim::PeriodicRunReport>* reports, double* wall_seconds) const {
  // Before the simulation (under a paced clock a whole run would be lost): the output must not
  // replace an input or an existing session without --force, and its folder must be writable.
  CheckOutputPath("--output", output, {truth.truth_path, matrix_path}, force);
  const auto start = std::chrono::steady_clock::now();
  const sim::SimulatedRig rig(truth.Load());
  const rig::MatrixPlan plan = matrix_path.empty() ? rig::StandardMatrixPlan() : rig::ReadMatrixFile(matrix_path);
  spdlog::info("simulated rig: {} ({}), {} experiments from {}", rig.model().composition(), rig.truth().source,
               plan.experiments.size(), plan.source);
  std::vector<sim::PeriodicRunReport> run_reports;
  daq::Session session = rig.RunMatrix(plan, run.Get(), &run_reports);
  daq::WriteSession(output, session);
  for (const sim::PeriodicRunReport& r : run_reports)
    if (!r.interlock.empty()) spdlog::warn("experiment {}: aborted by the interlock: {}", r.label, r.interlock);
  if (reports) *reports = std::move(run_reports);
  if (wall_seconds) *wall_seconds = Seconds(start);
  return session;
}

void SimMatrixCommand::Run() const {
  std::vector<sim::PeriodicRunReport> reports;
  double wall = 0.0;
  const daq::Session session = Record(&reports, &wall);
  std::cout << fmt::format("{:<4} {:>6} {:>7} {:>7} | {:>6} {:>9} {:>9} | {:>19} | {:>19} | {:>6} {:>8}\n", "exp",
                           "f Hz", "stat mm", "amp mm", "settle", "change", "track mm", "force kN", "pressure MPa g",
                           "steps", "wall ms");
  double simulated = 0.0;
  for (std::size_t i = 0; i < reports.size(); ++i) {
    const sim::PeriodicRunReport& r = reports[i];
    const daq::Experiment& e = session.experiments[i];
    simulated += r.simulated_seconds;
    std::cout << fmt::format("{:<4} {:>6.2f} {:>7.0f} {:>7.0f} | {:>5}{} {:>9.1e} {:>9.3f} | {} | {} | {:>6} {:>8.1f}\n",
                             e.label, e.frequency, e.static_position * 1e3, e.amplitude * 1e3, r.settle_periods,
                             r.settled ? " " : "!", r.record_change, r.actuator.max_tracking_error * 1e3,
                             RangeText(e.channel("force").samples, 1e-3), RangeText(e.channel("pressure").samples, 1e-6),
                             r.ida_steps, r.wall_seconds * 1e3);
  }
  std::cout << fmt::format("{} experiments, {:.1f} s simulated in {:.2f} s ({:.0f} simulated s per wall s); wrote {}\n",
                           reports.size(), simulated, wall, simulated / wall, output);
}

daq::Session SimDropCommand::Record(sim::DropRunReport* report, double* wall_seconds) const {
  CheckOutputPath("--output", output, {truth.truth_path}, force);
  const auto start = std::chrono::steady_clock::now();
  const sim::SimulatedRig rig(truth.Load());
  spdlog::info("simulated drop: {} kg at {} m/s for {} s on {} ({})", drop.mass, drop.impact_velocity, drop.duration,
               rig.model().composition(), rig.truth().source);
  sim::DropRunReport run_report;
  daq::Session session = rig.RunDropSession(drop, run.Get(), &run_report);
  daq::WriteSession(output, session);
  if (report) *report = run_report;
  if (wall_seconds) *wall_seconds = Seconds(start);
  return session;
}

void SimDropCommand::Run() const {
  sim::DropRunReport report;
  double wall = 0.0;
  const daq::Session session = Record(&report, &wall);
  std::cout << fmt::format(
      "drop {} kg at {} m/s: peak stroke {:.1f} mm, peak force {:.2f} kN, stroke after {} s {:.1f} mm\n", drop.mass,
      drop.impact_velocity, report.peak_stroke * 1e3, report.peak_force * 1e-3, drop.duration,
      report.final_stroke * 1e3);
  if (report.thermal_time_constant_fit > 0)
    std::cout << fmt::format(
        "gas cooling: time constant {:.2f} s fitted to T - T_amb over 20..80 % of the record; model "
        "theta15 / (theta16 (1 + theta6 q)) = {:.2f} s\n",
        report.thermal_time_constant_fit, report.thermal_time_constant_model);
  std::cout << fmt::format("{} samples at {} Hz, {} IDA steps, {:.2f} s wall; wrote {}\n",
                           session.experiments.front().sample_count(), session.experiments.front().sample_rate,
                           report.ida_steps, wall, output);
}

void RegisterSimCommand(CLI::App& app) {
  CLI::App* sim_app = app.add_subcommand("sim", "Run the simulated rig: test matrices and drop tests written as session files, and the truth it simulates.");
  sim_app->require_subcommand(1);

  auto [m, matrix] = AddCommand<SimMatrixCommand>(
      *sim_app, "matrix",
      "Run a test matrix (by default the 14 standard experiments) on the simulated rig and write the session.");
  AddSimMatrixOptions(*m, *matrix);

  auto [d, drop] = AddCommand<SimDropCommand>(
      *sim_app, "drop", "Drop a mass onto the fully extended damper and write the record as a session.");
  AddSimDropOptions(*d, *drop);

  auto [t, truth] = AddCommand<SimTruthCommand>(
      *sim_app, "truth", "Show the truth the rig simulates (a drawn unit's too), or write out the built-in default.");
  truth->truth.Add(*t);
  t->add_option("--write-default", truth->write_path, "Write the built-in default truth file to this path and stop.");
}

void AddSimMatrixOptions(CLI::App& m, SimMatrixCommand& command) {
  SimMatrixCommand* matrix = &command;
  matrix->truth.Add(m, true);
  matrix->run.Add(m);
  m.add_option("--matrix", matrix->matrix_path, "Read the test matrix from this TOML file (docs/simulated-rig.md).")->check(CLI::ExistingFile);
  m.add_option("-o,--output", matrix->output, "Session file to write (HDF5).")->required();
  m.add_flag("--force", matrix->force, "Replace an existing session file at the output path.");
}

void AddSimDropOptions(CLI::App& app, SimDropCommand& command) {
  CLI::App* d = &app;
  SimDropCommand* drop = &command;
  drop->truth.Add(*d);
  drop->run.Add(*d);
  d->add_option("--mass", drop->drop.mass, "The dropped mass in kg.")->check(Positive("kg"))->capture_default_str();
  d->add_option("--velocity", drop->drop.impact_velocity, "The stroke velocity at contact in m/s.")
      ->check(NonNegative("m/s"))
      ->capture_default_str();
  d->add_option("--duration", drop->drop.duration, "The record's length from contact in s.")
      ->check(Between(1e-3, 3600.0, "s"))
      ->capture_default_str();
  d->add_option("--label", drop->drop.label, "The experiment's label in the session.")->capture_default_str();
  d->add_option("-o,--output", drop->output, "Session file to write (HDF5).")->required();
  d->add_flag("--force", drop->force, "Replace an existing session file at the output path.");
}

}  // namespace strut::tools
