// strut rig run: the test matrix on the rig (rig::MatrixRunner, docs/rig-run.md) with the actuator
// controller over Modbus TCP and the acquisition over CAN (SocketCAN or the UDP transport),
// recorded into a session with the streaming recorder; pause (Ctrl-C once), stop (twice) and
// --resume into the same file.
#include <signal.h>
#include <spdlog/fmt/fmt.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>

#include "commands.h"
#include "option_checks.h"
#include "output_files.h"
#include "strut/daq/can_acquisition.h"
#include "strut/daq/modbus_controller.h"
#include "strut/daq/recorder.h"
#include "strut/ident/fit_report.h"
#include "strut/rig/matrix_runner.h"
#include "strut/rig/safety.h"
#include "strut/sim/can_module.h"
#include "strut/sim/recorded_truth.h"
#include "strut/sim/rig_server.h"
#include "strut/sim/simulated_rig.h"
#include "truth_options.h"

namespace strut::tools {
namespace {

// The runner of this process, for the signal handler (atomic stores only: async-signal-safe).
std::atomic<rig::MatrixRunner*> g_runner{nullptr};
std::atomic<int> g_interrupts{0};

extern "C" void OnSignal(int signal) {
  rig::MatrixRunner* runner = g_runner.load();
  const int n = ++g_interrupts;
  if (runner == nullptr) return;
  if (signal == SIGINT && n == 1) {
    runner->RequestPause();
  } else {
    runner->RequestStop();
  }
}

std::string Percent(double margin) {
  if (margin >= 1.0) return "-";
  return fmt::format("{:.0f}%", 100.0 * margin);
}

//! How fast --rig sim runs unless told: well inside what the served rig keeps up with.
constexpr double kDefaultSimSpeed = 50.0;

struct RigRunCommand {
  std::string rig_spec, daq_spec, matrix_path, serial, operator_name, limits_path, fit_path, output;
  std::optional<double> daq_rate;
  std::optional<long> periods;
  int ramp_cycles = 2;
  double static_rate = 0.01;
  int timeout_ms = 500;
  bool resume = false, force = false, no_progress = false;
  std::optional<double> speed;  // --rig sim only
  double drift_window = rig::SteadyStateTolerances{}.drift_window;
  TruthOptions truth_options;   // --rig sim only

  void Run() {
    // --rig sim: the simulated rig in this process, behind the same protocols as a real one.
    const bool simulated = rig_spec == "sim";
    if (simulated) {
      if (!daq_spec.empty() && daq_spec != "sim")
        throw std::invalid_argument(fmt::format("--daq {}: with --rig sim the acquisition is the simulated rig's own "
                                                "(give --daq sim or nothing)", daq_spec));
    } else {
      if (daq_spec.empty()) throw std::invalid_argument("--daq: the acquisition module is needed (can:IFACE or udp:HOST:PORT)");
      if (daq_spec == "sim") throw std::invalid_argument("--daq sim: the simulated acquisition comes with --rig sim only");
      if (speed) throw std::invalid_argument("--speed: only the simulated rig (--rig sim) runs faster than real time");
      if (!truth_options.truth_path.empty() || truth_options.draw_seed || truth_options.ideal_actuator ||
          truth_options.base_option->count() > 0 || truth_options.effect_option->count() > 0)
        throw std::invalid_argument(
            "--truth, --draw, --base, --effect and --ideal-actuator describe the simulated rig (--rig sim)");
    }
    std::optional<sim::Truth> truth;
    if (simulated) {
      truth = truth_options.Load();
      if (daq_rate && std::abs(*daq_rate - truth->acquisition.sample_rate) > 1e-9 * *daq_rate)
        throw std::invalid_argument(fmt::format("--daq-rate {} Hz: the simulated rig samples at its truth's {} Hz",
                                                *daq_rate, truth->acquisition.sample_rate));
      daq_rate = truth->acquisition.sample_rate;
      if (serial.empty() && !resume) serial = truth->damper_serial;
    }
    // Everything that can be refused is checked before anything connects or moves.
    std::vector<std::string> inputs;
    for (const std::string* p : {&matrix_path, &limits_path, &fit_path})
      if (!p->empty()) inputs.push_back(*p);
    const std::string journal = daq::JournalPath(output);
    if (resume) {
      if (force) throw std::invalid_argument("--resume and --force: a resume keeps what was recorded; give one");
      if (!std::filesystem::exists(journal)) {
        throw std::invalid_argument(fmt::format(
            "--resume: {} has no journal {} to go on from{}", output, journal,
            std::filesystem::exists(output) ? " (the session was completed, or recorded without keeping it)" : ""));
      }
    } else {
      CheckOutputPath("-o", output, inputs, force);
      if (std::filesystem::exists(journal) && !force)
        throw std::invalid_argument(fmt::format("-o {}: the journal {} of an interrupted run is there: --resume it, "
                                                "`strut recover` it, or give --force to start over",
                                                output, journal));
      if (serial.empty()) throw std::invalid_argument("--serial: the damper's serial number is needed for a new session");
    }
    sim::MatrixPlan plan = matrix_path.empty() ? sim::StandardMatrixPlan() : sim::ReadMatrixFile(matrix_path);
    std::string matrix_text = "standard";
    if (!matrix_path.empty()) {
      std::ifstream in(matrix_path);
      std::ostringstream text;
      text << in.rdbuf();
      matrix_text = text.str();
    }
    const double rate = daq_rate.value_or(plan.sample_rate.value_or(200.0));
    if (plan.sample_rate && std::abs(*plan.sample_rate - rate) > 1e-9 * rate)
      throw std::invalid_argument(fmt::format("--daq-rate {} Hz: the matrix {} wants sample_rate {} Hz", rate,
                                              matrix_path, *plan.sample_rate));
    const rig::SafetyConfig safety = limits_path.empty() ? rig::SafetyConfig{} : rig::ReadSafetyConfig(limits_path);
    rig::RunnerOptions options;
    options.periods = periods.value_or(plan.periods.value_or(3));
    options.ramp_cycles = ramp_cycles;
    options.static_rate = static_rate;
    options.reset_heartbeat_fault = resume;
    options.stream_speed = simulated ? speed.value_or(kDefaultSimSpeed) : 1.0;
    options.steady.drift_window = drift_window;
    std::string error;
    if (!options.IsValid(&error)) throw std::invalid_argument(error);

    rig::ResponsePredictor predictor;
    std::optional<ident::FitRecord> fit;
    if (!fit_path.empty()) {
      fit = ident::ReadFitJson(fit_path, ident::Causality::kStrokeInput);
      predictor = rig::FitPredictor(*fit);
    }

    // What to run: the whole matrix, or what a resumed session lacks.
    std::optional<daq::Recorder> recorder;
    std::vector<rig::RunItem> items;
    if (resume) {
      const daq::Session so_far = daq::ReadJournal(journal);
      if (!serial.empty() && serial != so_far.damper_serial)
        throw std::invalid_argument(fmt::format("--serial {}: the session {} is of damper {}", serial, output,
                                                so_far.damper_serial));
      items = rig::RemainingExperiments(plan.experiments, so_far);
    } else {
      for (const rig::MatrixEntry& e : plan.experiments) items.push_back({e});
    }
    if (resume && items.empty()) {
      // Cut off after the last record ended: nothing to run, the session only needs closing.
      daq::Recorder::Resume(output, {}, "strut rig run --resume: nothing left to run").Close();
      std::cout << fmt::format("{}: run complete (every experiment of the matrix was recorded already)\n", output);
      return;
    }
    std::vector<rig::MatrixEntry> entries;
    for (const rig::RunItem& i : items) entries.push_back(i.entry);
    const std::vector<std::string> refusals = rig::CheckMatrix(entries, safety, rate, predictor);
    if (!refusals.empty()) {
      throw std::invalid_argument(fmt::format("the matrix {} is refused before the rig moves (limits: {}):\n  {}",
                                              matrix_path.empty() ? "standard" : matrix_path,
                                              limits_path.empty() ? "defaults" : limits_path,
                                              fmt::join(refusals, "\n  ")));
    }

    // The devices.
    daq::ModbusControllerOptions modbus;
    if (!simulated) modbus.endpoint = daq::ParseModbusEndpoint(rig_spec);
    modbus.response_timeout = std::chrono::milliseconds(timeout_ms);
    daq::CanAcquisitionOptions can;
    std::unique_ptr<daq::CanTransport> transport;
    std::unique_ptr<sim::RigServer> server;  // --rig sim: stopped when the run ends, however it ends
    if (simulated) {
      transport = daq::OpenCanTransport("udp:127.0.0.1:0", /*listen=*/true);
      sim::RigServerOptions served;
      served.speed = options.stream_speed;
      served.can = transport->name();
      server = std::make_unique<sim::RigServer>(*truth, served);
      modbus.endpoint = server->modbus_endpoint();
      can = server->ReceiverOptions();
      server->Start();
      spdlog::info("simulated rig: controller at {}, sensors to {}, {}x real time", server->modbus_endpoint().host,
                   transport->name(), served.speed);
    } else {
      can.layout.channels = 3;
      can.layout.module = 1;
      can.sample_rate = rate;
      can.channels = sim::CanChannels(sim::SensorSet{});
      transport = daq::OpenCanTransport(daq_spec, /*listen=*/true);
    }
    daq::CanAcquisition acquisition(std::move(transport), can);
    daq::ModbusController controller(modbus);

    if (resume) {
      daq::Session so_far;
      recorder.emplace(daq::Recorder::Resume(output, {}, "strut rig run --resume", &so_far));
      spdlog::info("resuming {}: {} experiments recorded, {} to go", output, so_far.experiments.size(), items.size());
    } else {
      daq::RecordingMetadata m;
      m.damper_serial = serial;
      m.rig = controller.Describe() + " + " + daq_spec;
      if (simulated) {
        m.rig = fmt::format("{} [simulated in-process at {}x real time: {}]", truth->rig, options.stream_speed,
                            truth->source);
        daq::Session truth_holder;
        sim::RecordTruth(*truth, truth_holder);
        m.groups = truth_holder.metadata;
      }
      m.operator_name = operator_name;
      m.matrix = matrix_text;
      m.limits = {{"stroke_min", safety.stroke.lower},      {"stroke_max", safety.stroke.upper},
                  {"force_min", safety.force.lower},        {"force_max", safety.force.upper},
                  {"pressure_min", safety.pressure.lower},  {"pressure_max", safety.pressure.upper},
                  {"following_error", safety.following.max_error}, {"max_velocity", safety.actuator.max_velocity},
                  {"max_flow", safety.actuator.max_flow}};
      daq::RecorderOptions ro;
      ro.force = force;
      recorder.emplace(daq::Recorder::Open(output, m, ro));
    }
    if (fit) recorder->Event(daq::MonotonicNs(), "note", fmt::format("matrix checked against the fit {}", fit_path));

    rig::MatrixRunner runner(controller, acquisition, *recorder, safety, options);
    const bool tty = !no_progress && isatty(fileno(stderr));
    std::string last_line;
    runner.on_progress = [&](const rig::Progress& p) {
      if (p.experiment.empty()) return;  // starting: nothing to show yet
      const std::string where = fmt::format("{} ({}/{})", p.experiment, p.index + 1, p.total);
      const std::string measure = std::isfinite(p.steady_measure) ? fmt::format("{:.2f}", p.steady_measure) : "-";
      const std::string margins =
          fmt::format("margins stroke {} force {} pressure {} following {}", Percent(p.margins.stroke),
                      Percent(p.margins.force), Percent(p.margins.pressure), Percent(p.margins.following));
      if (tty) {
        std::fprintf(stderr, "\r\033[K%s  %-16s cycle %3ld  steady %5s  periods %ld/%ld  stroke %.4f m  force %.3f kN  %s",
                     where.c_str(), std::string(rig::ToString(p.phase)).c_str(), p.cycles, measure.c_str(),
                     p.periods_recorded, p.periods_requested, p.stroke, p.force * 1e-3, margins.c_str());
        std::fflush(stderr);
        return;
      }
      // Plain lines: one per phase change.
      const std::string line = fmt::format("{}: {}", where, rig::ToString(p.phase));
      if (line == last_line) return;
      last_line = line;
      spdlog::info("{} (cycle {}, steady-state measure {}, {})", line, p.cycles, measure, margins);
    };

    struct sigaction action {};
    action.sa_handler = OnSignal;
    sigemptyset(&action.sa_mask);
    struct sigaction old_int {}, old_term {};
    g_interrupts = 0;
    g_runner = &runner;
    sigaction(SIGINT, &action, &old_int);
    sigaction(SIGTERM, &action, &old_term);
    if (tty) spdlog::info("Ctrl-C once: pause after this experiment; twice: stop now (both resumable with --resume)");
    const rig::RunReport report = runner.Run(items);
    g_runner = nullptr;
    sigaction(SIGINT, &old_int, nullptr);
    sigaction(SIGTERM, &old_term, nullptr);
    if (tty) std::fprintf(stderr, "\r\033[K");

    const bool complete = report.outcome == rig::RunOutcome::kComplete;
    recorder->Close(/*keep_journal=*/!complete);
    std::cout << fmt::format("{}: run {}\n", output, rig::ToString(report.outcome));
    for (const auto& l : report.complete) std::cout << fmt::format("  {:<10} complete\n", l);
    for (const auto& l : report.not_steady) std::cout << fmt::format("  {:<10} not steady (recorded)\n", l);
    for (const auto& l : report.aborted) std::cout << fmt::format("  {:<10} aborted\n", l);
    if (!complete) {
      std::cout << fmt::format("  cause: {}\n  remaining: {}\n  resume with: strut rig run ... -o {} --resume\n",
                               report.cause, fmt::join(report.remaining, " "), output);
      throw ExitCode(report.outcome == rig::RunOutcome::kPaused ? kExitRunPaused : kExitRunAborted);
    }
  }
};

}  // namespace

void RegisterRigRunCommand(CLI::App& rig) {
  auto c = std::make_shared<RigRunCommand>();
  CLI::App* run = rig.add_subcommand(
      "run", "Run the test matrix on the rig and record it: controller over Modbus TCP, acquisition over CAN "
             "(docs/rig-run.md)");
  run->add_option("--rig", c->rig_spec,
                  "Actuator controller, modbus-tcp://HOST:PORT (or HOST:PORT), or sim: the simulated rig in this "
                  "process, served over Modbus TCP and CAN frames on loopback as strut rig serve-sim serves it.")
      ->required();
  run->add_option("--daq", c->daq_spec,
                  "Acquisition module: can:IFACE (SocketCAN) or udp:HOST:PORT (the UDP transport; listens there); "
                  "sim (or nothing) with --rig sim.");
  run->add_option("--speed", c->speed,
                  fmt::format("With --rig sim: simulated seconds per wall second (default {}; about 100 is what "
                              "this machine keeps up with, docs/simulated-rig.md).", kDefaultSimSpeed))
      ->check(Between(0.01, 1000.0));
  run->add_option("--daq-rate", c->daq_rate, "Sample sets per second the module sends (default: the matrix file's "
                                             "sample_rate, else 200 Hz).")
      ->check(Positive("Hz"));
  run->add_option("--matrix", c->matrix_path, "Matrix file (TOML, docs/simulated-rig.md); default the standard 14.")
      ->check(CLI::ExistingFile);
  run->add_option("--serial", c->serial, "Damper serial number (required for a new session).");
  run->add_option("--operator", c->operator_name, "Operator's name, kept in the session.");
  run->add_option("--limits", c->limits_path, "Limits and detector actions (TOML, docs/rig-run.md); default the "
                                              "documented defaults.")
      ->check(CLI::ExistingFile);
  run->add_option("--fit", c->fit_path, "A fit (JSON of strut identify): the matrix is refused when the force or "
                                        "pressure it predicts leaves the limits.")
      ->check(CLI::ExistingFile);
  run->add_option("--periods", c->periods, "Whole steady-state periods recorded per experiment (default: the "
                                           "matrix file's, else 3).")
      ->check(Between(1, 100000));
  run->add_option("--ramp-cycles", c->ramp_cycles, "Whole cycles of amplitude ramp in and out.")
      ->check(Between(0, 1000))
      ->capture_default_str();
  run->add_option("--static-rate", c->static_rate, "Rate limit of moves to a static position, m/s.")
      ->check(Positive("m/s"))
      ->capture_default_str();
  run->add_option("--drift-window", c->drift_window,
                  "Seconds over which the mean pressure must have stopped drifting (2e-4 of it) before an "
                  "experiment counts as steady; 0 switches that test off (docs/rig-run.md).")
      ->check(Between(0.0, 500.0, "s"))
      ->capture_default_str();
  run->add_option("--timeout", c->timeout_ms, "Modbus response timeout, ms.")->check(Between(1, 60000))->capture_default_str();
  run->add_option("-o,--output", c->output, "Session file (HDF5) to record.")->required();
  run->add_flag("--resume", c->resume, "Go on with an interrupted run into the same session (its journal).");
  run->add_flag("--force", c->force, "Replace an existing session or journal at the output.");
  run->add_flag("--no-progress", c->no_progress, "No live progress line on a terminal.");
  c->truth_options.Add(*run, /*with_actuator=*/true);
  run->callback([c] { c->Run(); });
}

}  // namespace strut::tools
