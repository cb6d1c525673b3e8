// strut rig ...: the rig's devices. `rig controller-status` reads the actuator controller over
// Modbus TCP and prints its status and set-point (docs/register-map.md); `rig serve-sim` serves
// the simulated rig behind the real protocols (sim::RigServer, docs/simulated-rig.md).
#include <spdlog/fmt/fmt.h>

#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <csignal>
#include <iostream>
#include <thread>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "commands.h"
#include "option_checks.h"
#include "stop_signals.h"
#include "strut/daq/modbus_controller.h"
#include "strut/sim/rig_server.h"
#include "truth_options.h"

namespace strut::tools {
namespace {

struct ControllerStatusOptions {
  std::string modbus;
  int timeout_ms = 1000;
  bool json = false;
};

nlohmann::ordered_json StatusJson(const daq::ControllerStatus& s) {
  return {{"state", std::string(daq::ToString(s.state))},
          {"mode", std::string(daq::ToString(s.mode))},
          {"status_word", s.status_word},
          {"status", daq::StatusBitsText(s.status_word)},
          {"fault_word", s.fault_word},
          {"faults", daq::FaultBitsText(s.fault_word)},
          {"applied_sequence", s.applied_sequence},
          {"heartbeat", s.heartbeat},
          {"stroke", s.stroke},
          {"force", s.force},
          {"command", s.command},
          {"cycles", s.cycles},
          {"time_ms", s.time_ms}};
}

nlohmann::ordered_json SetPointJson(const daq::SetPoint& s) {
  return {{"mode", std::string(daq::ToString(s.mode))},
          {"static_position", s.static_position},
          {"amplitude", s.amplitude},
          {"frequency", s.frequency},
          {"ramp_cycles", s.ramp_cycles},
          {"static_rate", s.static_rate},
          {"stroke_min", s.limits.stroke_min},
          {"stroke_max", s.limits.stroke_max},
          {"force_min", s.limits.force_min},
          {"force_max", s.limits.force_max}};
}

void RunControllerStatus(const ControllerStatusOptions& o) {
  daq::ModbusControllerOptions options;
  options.endpoint = daq::ParseModbusEndpoint(o.modbus);
  options.response_timeout = std::chrono::milliseconds(o.timeout_ms);
  daq::ModbusController controller(options);
  const daq::ControllerStatus status = controller.ReadStatus();
  // The set-point block may be half-written or never written; the status is still worth showing.
  std::optional<daq::SetPoint> set_point;
  std::string set_point_problem;
  try {
    set_point = controller.ReadSetPoint();
  } catch (const daq::DeviceError& e) {
    set_point_problem = e.detail();
  }
  if (o.json) {
    nlohmann::ordered_json j = {{"controller", controller.Describe()}, {"status", StatusJson(status)}};
    j["set_point"] = set_point ? SetPointJson(*set_point) : nlohmann::ordered_json(nullptr);
    if (!set_point) j["set_point_problem"] = set_point_problem;
    std::cout << j.dump(2) << "\n";
    return;
  }
  const char* unit = status.mode == daq::ControlMode::kStroke ? "m" : "N";
  std::cout << fmt::format("controller  {}\n", controller.Describe())
            << fmt::format("state       {} ({} control)\n", daq::ToString(status.state), daq::ToString(status.mode))
            << fmt::format("status      0x{:04x} {}\n", status.status_word, daq::StatusBitsText(status.status_word))
            << fmt::format("faults      0x{:04x} {}\n", status.fault_word, daq::FaultBitsText(status.fault_word))
            << fmt::format("stroke      {:.6g} m\n", status.stroke)
            << fmt::format("force       {:.6g} N\n", status.force)
            << fmt::format("command     {:.6g} {}\n", status.command, unit)
            << fmt::format("cycles      {}\n", status.cycles)
            << fmt::format("sequence    {} (applied set-point)\n", status.applied_sequence)
            << fmt::format("heartbeat   {}\n", status.heartbeat)
            << fmt::format("clock       {:.3f} s\n", status.time_ms / 1000.0);
  if (set_point) {
    const daq::SetPoint& s = *set_point;
    const char* u = s.mode == daq::ControlMode::kStroke ? "m" : "N";
    std::cout << fmt::format(
        "set-point   {} control: static {:.6g} {}, amplitude {:.6g} {} at {:.6g} Hz, ramp {} cycles, "
        "static rate {:.6g} {}/s\n"
        "limits      stroke {:.6g} .. {:.6g} m, force {:.6g} .. {:.6g} N\n",
        daq::ToString(s.mode), s.static_position, u, s.amplitude, u, s.frequency, s.ramp_cycles, s.static_rate, u,
        s.limits.stroke_min, s.limits.stroke_max, s.limits.force_min, s.limits.force_max);
  } else {
    std::cout << fmt::format("set-point   not readable: {}\n", set_point_problem);
  }
}

struct ServeSimOptions {
  TruthOptions truth;
  std::string listen = "127.0.0.1:1502";
  std::string can = "udp:127.0.0.1:5000";
  bool fd = false;
  double speed = 1.0;
  unsigned long seed = 1;
  double duration = 0.0;
  double log_interval = 10.0;
  sim::SimulatedControllerOptions controller;
};

// SIGINT and SIGTERM end serve-sim cleanly (the main thread polls the flag).
volatile std::sig_atomic_t g_stop_signal = 0;
extern "C" void OnStopSignal(int signal) { g_stop_signal = signal; }

void RunServeSim(const ServeSimOptions& o) {
  const daq::ModbusEndpoint endpoint = daq::ParseModbusEndpoint(o.listen);
  sim::RigServerOptions options;
  options.modbus.host = endpoint.host;
  options.modbus.port = endpoint.port;
  options.can = o.can;
  options.can_fd = o.fd;
  options.speed = o.speed;
  options.controller = o.controller;
  options.controller.seed = o.seed;
  sim::RigServer server(o.truth.Load(), options);
  const sim::Truth& truth = server.controller().truth();
  const daq::CanAcquisitionOptions stream = server.ReceiverOptions();
  spdlog::info("simulated rig: {} ({}), damper {}", truth.BuildModel(ident::Causality::kStrokeInput).composition(),
               truth.source, truth.damper_serial);
  spdlog::info("controller on {}; acquisition module {} sends {} frames to {}: {} channels at {} Hz", endpoint.ToString(),
               static_cast<int>(stream.layout.module), stream.layout.fd ? "CAN FD" : "classic CAN", o.can,
               stream.channels.size(), stream.sample_rate);
  spdlog::info("speed {:g} simulated s per wall s; stop with Ctrl-C{}", o.speed,
               o.duration > 0 ? fmt::format(" or after {:g} s", o.duration) : "");
  const auto log_status = [&] {
    const daq::ControllerStatus s = server.controller().Status();
    const sim::RigServerStats st = server.stats();
    spdlog::info("t = {:.1f} s: {} [{}] faults {}, stroke {:.2f} mm, force {:.2f} kN, cycles {}; {} sets sent, "
                 "{:.0f} simulated s per CPU s, behind by at most {:.2f} s",
                 st.simulated_seconds, daq::ToString(s.state), daq::StatusBitsText(s.status_word),
                 daq::FaultBitsText(s.fault_word), s.stroke * 1e3, s.force * 1e-3, s.cycles, st.sets_sent,
                 st.compute_seconds > 0 ? st.simulated_seconds / st.compute_seconds : 0.0, st.max_lateness);
  };
  {
    g_stop_signal = 0;
    const StopSignals signals(OnStopSignal);
    server.Start();
    const auto start = std::chrono::steady_clock::now();
    auto next_log = start + std::chrono::duration<double>(o.log_interval);
    for (;;) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      const auto now = std::chrono::steady_clock::now();
      if (g_stop_signal) {
        spdlog::info("signal {}: stopping", static_cast<int>(g_stop_signal));
        break;
      }
      if (o.duration > 0 && now - start >= std::chrono::duration<double>(o.duration)) break;
      if (server.error()) break;
      if (o.log_interval > 0 && now >= next_log) {
        log_status();
        next_log += std::chrono::duration<double>(o.log_interval);
      }
    }
    server.Stop();
  }
  log_status();
  if (const auto error = server.error()) throw std::runtime_error("simulated rig: the stream failed: " + *error);
}

}  // namespace

void RegisterRigCommand(CLI::App& app) {
  CLI::App* rig = app.add_subcommand("rig", "The rig's devices: actuator controller and acquisition");
  rig->require_subcommand(1);
  auto options = std::make_shared<ControllerStatusOptions>();
  CLI::App* status = rig->add_subcommand(
      "controller-status", "Read the actuator controller over Modbus TCP and print its status and set-point");
  status->add_option("--modbus", options->modbus, "Controller endpoint, HOST:PORT or modbus-tcp://HOST:PORT.")
      ->required();
  status->add_option("--timeout", options->timeout_ms, "Response timeout, ms (also the connect timeout).")
      ->check(Between(1, 60000));
  status->add_flag("--json", options->json, "Print JSON instead of text.");
  status->callback([options] { RunControllerStatus(*options); });

  auto serve = std::make_shared<ServeSimOptions>();
  CLI::App* sim = rig->add_subcommand(
      "serve-sim",
      "Serve the simulated rig behind the real protocols: its controller over Modbus TCP and its sensors as CAN frames "
      "over UDP, paced by the simulation clock, until Ctrl-C, SIGTERM or --duration.");
  serve->truth.Add(*sim, true);
  sim->add_option("--listen", serve->listen, "Where the controller listens for Modbus TCP, HOST:PORT (an IPv4 address; 0.0.0.0 for every interface).")
      ->capture_default_str();
  sim->add_option("--can", serve->can, "Where the acquisition module sends its CAN frames: udp:HOST:PORT (or can:IFACE with SocketCAN).")
      ->capture_default_str();
  sim->add_flag("--fd", serve->fd, "Send CAN FD frames (8 sample sets each) instead of classic CAN frames (one each).");
  sim->add_option("--speed", serve->speed, "Simulated seconds per wall second (docs/simulated-rig.md says how fast this machine can go).")
      ->check(Between(1e-3, 1e4))
      ->capture_default_str();
  sim->add_option("--seed", serve->seed, "The seed of the sensor noise and faults: the same seed and the same commands give the same samples.")
      ->capture_default_str();
  sim->add_option("--duration", serve->duration, "Stop after this many wall-clock seconds (0: run until a signal).")
      ->check(NonNegative("s"))
      ->capture_default_str();
  sim->add_option("--initial-stroke", serve->controller.initial_stroke, "The stroke where the piston rests before the first arm, in m (LVDT reading); default on its top-out stop, where an unloaded strut rests.")
      ->check(Between(-1.0, 1.0, "m"));
  sim->add_option("--following-error", serve->controller.following_error_limit, "The following-error interlock: command minus stroke beyond this many m latches a fault (0: off).")
      ->check(NonNegative("m"))
      ->capture_default_str();
  sim->add_option("--log-interval", serve->log_interval, "Log the rig's status every this many wall-clock seconds (0: only at the end).")
      ->check(NonNegative("s"))
      ->capture_default_str();
  sim->callback([serve] { RunServeSim(*serve); });
}

}  // namespace strut::tools
