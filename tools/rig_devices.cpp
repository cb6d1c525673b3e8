// The devices of a matrix run (rig_devices.h).
#include "rig_devices.h"

#include <spdlog/spdlog.h>

#include "strut/sim/recorded_truth.h"

namespace strut::tools {

RigDevices ConnectRig(const daq::ModbusEndpoint& endpoint, std::chrono::milliseconds response_timeout,
                      const std::string& daq_spec, daq::CanAcquisitionOptions can) {
  RigDevices d;
  d.daq_spec = daq_spec;
  d.acquisition =
      std::make_unique<daq::CanAcquisition>(daq::OpenCanTransport(daq_spec, /*listen=*/true), std::move(can));
  daq::ModbusControllerOptions modbus;
  modbus.endpoint = endpoint;
  modbus.response_timeout = response_timeout;
  d.controller = std::make_unique<daq::ModbusController>(modbus);
  return d;
}

RigDevices ServeSimulatedRig(const sim::Truth& truth, double speed, std::chrono::milliseconds response_timeout) {
  RigDevices d;
  // The receiver first, on an ephemeral port, so the served module knows where to send.
  std::unique_ptr<daq::CanTransport> transport = daq::OpenCanTransport("udp:127.0.0.1:0", /*listen=*/true);
  d.daq_spec = transport->name();
  sim::RigServerOptions served;
  served.speed = speed;
  served.can = d.daq_spec;
  d.server = std::make_unique<sim::RigServer>(truth, served);
  d.acquisition = std::make_unique<daq::CanAcquisition>(std::move(transport), d.server->ReceiverOptions());
  daq::ModbusControllerOptions modbus;
  modbus.endpoint = d.server->modbus_endpoint();
  modbus.response_timeout = response_timeout;
  d.controller = std::make_unique<daq::ModbusController>(modbus);
  d.server->Start();
  spdlog::info("simulated rig: controller at {}, sensors to {}, {}x real time", modbus.endpoint.ToString(), d.daq_spec,
               speed);
  return d;
}

daq::RecordingMetadata RunMetadata(const std::string& serial, const std::string& rig, const std::string& operator_name,
                                   const std::string& matrix, const rig::SafetyConfig& safety,
                                   const std::optional<sim::Truth>& truth) {
  daq::RecordingMetadata m;
  m.damper_serial = serial;
  m.rig = rig;
  m.operator_name = operator_name;
  m.matrix = matrix;
  m.limits = {{"stroke_min", safety.stroke.lower},      {"stroke_max", safety.stroke.upper},
              {"force_min", safety.force.lower},        {"force_max", safety.force.upper},
              {"pressure_min", safety.pressure.lower},  {"pressure_max", safety.pressure.upper},
              {"following_error", safety.following.max_error}, {"max_velocity", safety.actuator.max_velocity},
              {"max_flow", safety.actuator.max_flow}};
  if (truth) {
    daq::Session holder;
    sim::RecordTruth(*truth, holder);
    m.groups = holder.metadata;
  }
  return m;
}

StopSignals::StopSignals(void (*handler)(int)) {
  struct sigaction action {};
  action.sa_handler = handler;
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, &old_int_);
  sigaction(SIGTERM, &action, &old_term_);
}

StopSignals::~StopSignals() {
  sigaction(SIGINT, &old_int_, nullptr);
  sigaction(SIGTERM, &old_term_, nullptr);
}

}  // namespace strut::tools
