// strut rig ...: the rig's devices. `rig controller-status` reads the actuator controller over
// Modbus TCP and prints its status and set-point (docs/register-map.md).
#include <spdlog/fmt/fmt.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <iostream>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "commands.h"
#include "strut/daq/modbus_controller.h"
#include "option_checks.h"

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
}

}  // namespace strut::tools
