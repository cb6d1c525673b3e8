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
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <iostream>
#include <memory>
#include <optional>
#include <string>

#include "commands.h"
#include "rig_run_request.h"
#include "option_checks.h"
#include "output_files.h"
#include "stop_signals.h"
#include "strut/daq/recorder.h"
#include "strut/daq/rig_devices.h"
#include "strut/ident/fit_record.h"
#include "strut/rig/campaign.h"
#include "strut/rig/channel_file.h"
#include "strut/rig/matrix_runner.h"
#include "strut/monitor/server.h"
#include "strut/rig/safety.h"
#include "strut/rig/test_matrix.h"
#include "strut/sim/can_module.h"
#include "strut/sim/recorded_truth.h"
#include "strut/sim/rig_server.h"
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

monitor::MonitorOptions MonitorOptionsOf(const std::string& endpoint, bool control) {
  monitor::MonitorOptions o = monitor::ParseMonitorEndpoint(endpoint);
  o.control = control;
  return o;
}

std::string Percent(double margin) {
  if (margin >= 1.0) return "-";
  return fmt::format("{:.0f}%", 100.0 * margin);
}

//! The progress of a run: a live line on a terminal, else a line per phase change.
std::function<void(const rig::Progress&)> ProgressDisplay(bool tty) {
  return [tty, last_line = std::string()](const rig::Progress& p) mutable {
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
}

//! How fast --rig sim runs unless told: well inside what the served rig keeps up with.
constexpr double kDefaultSimSpeed = 50.0;

struct RigRunCommand {
  std::string rig_spec, daq_spec, channels_path, matrix_path, serial, operator_name, limits_path, fit_path, output;
  std::optional<double> daq_rate;
  std::optional<long> periods;
  int ramp_cycles = 2;
  double static_rate = 0.01;
  int timeout_ms = 500;
  bool resume = false, force = false, no_progress = false;
  std::optional<double> speed;  // a simulated rig's clock: in-process, or served at that speed
  double drift_window = rig::SteadyStateTolerances{}.drift_window;
  TruthOptions truth_options;   // a simulated rig's truth: in-process, or served with the same options
  std::string monitor_endpoint;  // --monitor [HOST:PORT]
  CLI::Option* monitor_option = nullptr;
  bool monitor_control = false;
  bool no_top_out = false;
  rig::TopOutOptions top_out;

  //! The truth of a simulated rig: run here (--rig sim), or served by `strut rig serve-sim` with
  //! the same options, which the runner cannot ask; either way the session records it. Takes the
  //! sample rate and the serial number from it; refuses options that do not go with --rig sim.
  std::optional<sim::Truth> SimulatedTruth(bool simulated) {
    const bool truth_given = !truth_options.truth_path.empty() || truth_options.draw_seed ||
                             truth_options.ideal_actuator || truth_options.base_option->count() > 0 ||
                             truth_options.effect_option->count() > 0;
    if (simulated) {
      if (!daq_spec.empty() && daq_spec != "sim")
        throw std::invalid_argument(fmt::format("--daq {}: with --rig sim the acquisition is the simulated rig's own "
                                                "(give --daq sim or nothing)", daq_spec));
      if (!channels_path.empty())
        throw std::invalid_argument(fmt::format("--channels {}: with --rig sim the acquisition is the simulated rig's "
                                                "own", channels_path));
    } else {
      if (daq_spec.empty()) throw std::invalid_argument("--daq: the acquisition module is needed (can:IFACE or udp:HOST:PORT)");
      if (daq_spec == "sim") throw std::invalid_argument("--daq sim: the simulated acquisition comes with --rig sim only");
    }
    if (!simulated && !truth_given) return std::nullopt;
    sim::Truth truth = truth_options.Load();
    if (daq_rate && std::abs(*daq_rate - truth.acquisition.sample_rate) > 1e-9 * *daq_rate)
      throw std::invalid_argument(fmt::format("--daq-rate {} Hz: the simulated rig samples at its truth's {} Hz",
                                              *daq_rate, truth.acquisition.sample_rate));
    daq_rate = truth.acquisition.sample_rate;
    if (serial.empty() && !resume) serial = truth.damper_serial;
    return truth;
  }

  //! Where the devices are: the controller, the acquisition module and its frames.
  daq::RigConnection Connection(const std::optional<rig::ChannelMap>& channel_map,
                                const std::optional<sim::Truth>& truth, double rate, double stream_speed) const {
    daq::RigConnection connection;
    connection.controller = rig_spec;
    connection.acquisition = daq_spec;
    connection.response_timeout = std::chrono::milliseconds(timeout_ms);
    if (channel_map) {
      connection.can.layout = channel_map->layout;
      connection.can.channels = channel_map->channels;
    } else {  // the simulated rig's module: what serve-sim (of this truth) and the tests' plants stream
      connection.can.layout.channels = 3;
      connection.can.layout.module = 1;
      connection.can.channels = sim::CanChannels(truth ? truth->sensors : sim::SensorSet{});
    }
    connection.can.sample_rate = rate * stream_speed;
    return connection;
  }

  //! How the run ended, on stdout; a run that did not complete ends with its exit code.
  void PrintOutcome(const rig::RunReport& report) const {
    spdlog::info("the samples arrived at most {:.3f} s behind their own clock (lag limit {:.1f} s)", report.largest_lag,
                 report.lag_limit);
    std::cout << fmt::format("{}: run {}\n", output, rig::ToString(report.outcome));
    if (report.top_out)
      std::cout << fmt::format("  top-out    stroke zero {:.4f} mm, sd {:.4f} mm (recorded in /calibration)\n",
                               report.top_out->zero * 1e3, report.top_out->sd * 1e3);
    else if (!report.top_out_failure.empty())
      std::cout << fmt::format("  top-out    not found: {} (recorded without a stroke zero)\n", report.top_out_failure);
    for (const auto& l : report.complete) std::cout << fmt::format("  {:<10} complete\n", l);
    for (const auto& l : report.not_steady) std::cout << fmt::format("  {:<10} not steady (recorded)\n", l);
    for (const auto& l : report.aborted) std::cout << fmt::format("  {:<10} aborted\n", l);
    if (report.outcome == rig::RunOutcome::kComplete) return;
    std::cout << fmt::format("  cause: {}\n  remaining: {}\n  resume with: strut rig run ... -o {} --resume\n",
                             report.cause, fmt::join(report.remaining, " "), output);
    throw ExitCode(report.outcome == rig::RunOutcome::kPaused ? kExitRunPaused : kExitRunAborted);
  }

  void Run() {
    // --rig sim: the simulated rig in this process, behind the same protocols as a real one.
    const bool simulated = rig_spec == "sim";
    const std::optional<sim::Truth> truth = SimulatedTruth(simulated);
    const double stream_speed = speed.value_or(simulated ? kDefaultSimSpeed : 1.0);
    if (!simulated && stream_speed != 1.0)
      spdlog::warn("--speed {}: the stream is taken to arrive {} times faster than it is recorded, as from `strut rig "
                   "serve-sim --speed {}`; a real rig streams in real time",
                   stream_speed, stream_speed, stream_speed);
    // Everything that can be refused is checked before anything connects or moves.
    std::vector<std::string> inputs;
    for (const std::string* p : {&matrix_path, &limits_path, &fit_path, &channels_path})
      if (!p->empty()) inputs.push_back(*p);
    const rig::RunStart start{output, resume, force, serial};
    if (!resume) CheckOutputPath("-o", output, inputs, force);
    rig::CheckStart(start, rig::OutputState::Of(output));
    const std::string matrix_text = matrix_path.empty() ? "standard" : rig::ReadMatrixText(matrix_path);
    const rig::MatrixPlan plan = matrix_path.empty() ? rig::StandardMatrixPlan() : rig::ParseMatrix(matrix_text, matrix_path);
    const double rate = rig::RunSampleRate(daq_rate, plan);
    const rig::SafetyConfig safety = limits_path.empty() ? rig::SafetyConfig{} : rig::ReadSafetyConfig(limits_path);
    std::optional<rig::ChannelMap> channel_map;
    if (!channels_path.empty()) channel_map = rig::ReadChannelFile(channels_path);
    rig::RunnerOptions options;
    if (channel_map) options.pressure_reference = channel_map->pressure_reference;
    options.periods = periods.value_or(plan.periods.value_or(3));
    options.ramp_cycles = ramp_cycles;
    options.static_rate = static_rate;
    options.reset_heartbeat_fault = resume;
    options.stream_speed = stream_speed;
    options.steady.drift_window = drift_window;
    options.top_out = rig::TopOutToRun(start, !no_top_out, top_out);
    std::string error;
    if (!options.IsValid(&error)) throw std::invalid_argument(error);

    rig::ResponsePredictor predictor;
    std::optional<ident::FitRecord> fit;
    if (!fit_path.empty()) {
      fit = ident::ReadFitJson(fit_path, ident::Causality::kStrokeInput);
      predictor = rig::FitPredictor(*fit);
    }

    // What to run: the whole matrix, or what a resumed session lacks.
    std::optional<daq::Session> so_far;
    if (resume) so_far = daq::ReadJournal(daq::JournalPath(output));
    const std::vector<rig::RunItem> items = rig::ExperimentsToRun(start, plan.experiments, so_far ? &*so_far : nullptr);
    if (resume && items.empty()) {
      rig::CloseCompletedResume(output);
      std::cout << fmt::format("{}: run complete (every experiment of the matrix was recorded already)\n", output);
      return;
    }
    rig::RefuseUnsafeMatrix(items, safety, rate, predictor, matrix_path.empty() ? "standard" : matrix_path,
                            limits_path.empty() ? "defaults" : limits_path, options.top_out);

    // The devices: the simulated rig in this process, or a rig on the network.
    const daq::NetworkRigFactory network;
    std::optional<sim::SimulatedRigFactory> served;
    if (simulated) served.emplace(*truth, stream_speed);
    std::vector<const daq::RigDeviceFactory*> factories{&network};
    if (served) factories.push_back(&*served);
    const daq::RigDevices devices =
        daq::ConnectRig(Connection(channel_map, truth, rate, stream_speed), factories);

    daq::RecordingMetadata metadata;
    if (!resume) {
      std::string rig_text = devices.description;
      if (truth && !simulated)
        rig_text += fmt::format(" [{} served at {}x real time: {}]", truth->rig, stream_speed, truth->source);
      metadata = rig::RunMetadata(serial, rig_text, operator_name, matrix_text, safety);
      if (truth) metadata.groups = sim::TruthMetadata(*truth);
    }
    daq::Recorder recorder = rig::OpenRunRecorder(start, metadata, items.size());
    if (fit) recorder.Event(daq::MonotonicNs(), "note", fmt::format("matrix checked against the fit {}", fit_path));

    rig::MatrixRunner runner(*devices.controller, *devices.acquisition, recorder, safety, options);
    const bool tty = !no_progress && isatty(fileno(stderr));
    runner.on_progress = ProgressDisplay(tty);
    std::optional<monitor::MonitorFeed> feed;
    std::optional<monitor::MonitorServer> page;
    if (monitor_option && monitor_option->count() > 0) {
      const monitor::MonitorOptions where = MonitorOptionsOf(monitor_endpoint, monitor_control);
      const daq::StreamDescription& stream = devices.acquisition->description();
      std::vector<std::string> names;
      for (const daq::ChannelDescriptor& ch : stream.channels) names.push_back(ch.name);
      feed.emplace(names, stream.sample_rate, stream_speed);
      page.emplace(*feed, monitor::MonitorSetup{fmt::format("{} ({})", output, devices.description), items, safety, options.steady},
                   where,
                   monitor::MonitorControls{[&runner] { runner.RequestPause(); }, [&runner] { runner.RequestStop(); }});
      spdlog::info("monitor: {}{}", page->url(), monitor_control ? " (pause and stop buttons for this machine)" : "");
      runner.on_progress = [display = runner.on_progress, &feed](const rig::Progress& p) {
        display(p);
        feed->Progress(p);
      };
      runner.on_event = [&feed](std::string_view kind, const std::string& text) { feed->Event(kind, text); };
      runner.on_block = [&feed](const daq::AcquiredBlock& block) { feed->Block(block); };
    }

    g_interrupts = 0;
    g_runner = &runner;
    const rig::RunReport report = [&] {
      const StopSignals signals(OnSignal);
      if (tty) spdlog::info("Ctrl-C once: pause after this experiment; twice: stop now (both resumable with --resume)");
      return runner.Run(items);
    }();
    g_runner = nullptr;
    if (tty) std::fprintf(stderr, "\r\033[K");
    if (feed) {
      feed->Flush();
      page->Stop();  // after the pages have the run's last event
    }

    recorder.Close(/*keep_journal=*/report.outcome != rig::RunOutcome::kComplete);
    PrintOutcome(report);
  }
};

}  // namespace

void RunMatrixOnRig(const RigRunRequest& request) {
  RigRunCommand c;
  c.rig_spec = request.rig_spec;
  c.daq_spec = request.daq_spec;
  c.matrix_path = request.matrix_path;
  c.limits_path = request.limits_path;
  c.output = request.output;
  c.force = request.force;
  c.no_progress = request.no_progress;
  c.speed = request.speed;
  if (request.truth) c.truth_options = *request.truth;
  c.Run();
}

void RegisterRigRunCommand(CLI::App& rig) {
  auto [run, c] = AddCommand<RigRunCommand>(
      rig, "run",
      "Run the test matrix on the rig and record it: controller over Modbus TCP, acquisition over CAN "
      "(docs/rig-run.md)");
  run->add_option("--rig", c->rig_spec,
                  "Actuator controller, modbus-tcp://HOST:PORT (or HOST:PORT), or sim: the simulated rig in this "
                  "process, served over Modbus TCP and CAN frames on loopback as strut rig serve-sim serves it. "
                  "--truth, --draw, --base, --effect and --ideal-actuator give the simulated rig's truth: the one "
                  "run here, or, with a rig served by strut rig serve-sim, the options it was given (the runner "
                  "cannot ask it), which the session records as /truth.")
      ->required();
  run->add_option("--daq", c->daq_spec,
                  "Acquisition module: can:IFACE (SocketCAN) or udp:HOST:PORT (the UDP transport; listens there); "
                  "sim (or nothing) with --rig sim.");
  run->add_option("--speed", c->speed,
                  fmt::format("Simulated seconds per wall second of a simulated rig: with --rig sim (default {}; about "
                              "100 is what this machine keeps up with, docs/simulated-rig.md), or with a rig served by "
                              "`strut rig serve-sim --speed X` (give the same X: the stream arrives X times faster "
                              "than it is recorded). A real rig streams in real time (1, the default).",
                              kDefaultSimSpeed))
      ->check(Between(0.01, 1000.0));
  run->add_option("--channels", c->channels_path,
                  "Channel file (TOML, docs/rig-run.md): the acquisition module's number, frame kind and, per "
                  "channel, its place in the sample set and calibration; default the simulated rig's module "
                  "(module 1, classic frames, stroke force pressure in 16-bit counts over its sensors' ranges).")
      ->check(CLI::ExistingFile);
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
  run->add_flag("--no-top-out", c->no_top_out,
                "No top-out reference before the matrix: the session records no stroke zero and identify keeps its "
                "2 mm prior on theta12 (a resumed run never repeats the reference).");
  run->add_option("--top-out-rate", c->top_out.rate,
                  "Rate of the top-out reference's search toward full extension, m/s (the move goes on for the "
                  "runner's reaction time after the contact shows).")
      ->check(Between(1e-6, 0.01, "m/s"))
      ->capture_default_str();
  run->add_option("--top-out-force", c->top_out.force_drop,
                  "The top-out reference's force limit: the contact shows when the force falls this many N below its "
                  "trend, and the search turns back.")
      ->check(Between(10.0, 2.0e4, "N"))
      ->capture_default_str();
  run->add_option("--top-out-from", c->top_out.from,
                  "Stroke reading where the top-out search starts, m (above every stroke zero the transducer may have).")
      ->check(Between(-0.1, 0.1, "m"))
      ->capture_default_str();
  run->add_option("--top-out-to", c->top_out.to,
                  "Stroke reading where the top-out search ends without a contact, m (inside the stroke limits).")
      ->check(Between(-0.1, 0.1, "m"))
      ->capture_default_str();
  run->add_option("--timeout", c->timeout_ms, "Modbus response timeout, ms.")->check(Between(1, 60000))->capture_default_str();
  run->add_option("-o,--output", c->output, "Session file (HDF5) to record.")->required();
  run->add_flag("--resume", c->resume, "Go on with an interrupted run into the same session (its journal).");
  run->add_flag("--force", c->force, "Replace an existing session or journal at the output.");
  run->add_flag("--no-progress", c->no_progress, "No live progress line on a terminal.");
  c->monitor_option = run->add_option("--monitor", c->monitor_endpoint,
                                      "Serve a live view of the run as a web page at HOST:PORT (default 127.0.0.1:8080; "
                                      "port 0: any free port, logged): traces with the limits, the loops, margins, the "
                                      "steady-state test, the matrix, events (docs/monitor.md).")
                          ->expected(0, 1);
  run->add_flag("--monitor-control", c->monitor_control,
                "With --monitor: pause and stop buttons on the page (as Ctrl-C once and twice), for requests from this "
                "machine only.");
  c->truth_options.Add(*run, /*with_actuator=*/true);
}

}  // namespace strut::tools
