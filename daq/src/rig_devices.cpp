// The devices of a rig from connection strings (rig_devices.h).
#include "strut/daq/rig_devices.h"

#include <spdlog/fmt/fmt.h>

#include <stdexcept>
#include <string_view>
#include <vector>

#include "strut/daq/can_transport.h"
#include "strut/daq/modbus_controller.h"

namespace strut::daq {

std::string NetworkRigFactory::Accepted() const {
  return "modbus-tcp://HOST:PORT or HOST:PORT (a controller on the network, the acquisition module at can:IFACE or udp:HOST:PORT)";
}

bool NetworkRigFactory::Accepts(const RigConnection& connection) const {
  const std::string_view c = connection.controller;
  if (c.rfind("modbus-tcp://", 0) == 0) return true;
  // Without a scheme: HOST:PORT or [IPV6]:PORT, which ParseModbusEndpoint checks in full.
  return c.find("://") == std::string_view::npos && c.find(':') != std::string_view::npos;
}

RigDevices NetworkRigFactory::Connect(const RigConnection& connection) const {
  ModbusControllerOptions modbus;
  modbus.endpoint = ParseModbusEndpoint(connection.controller);
  modbus.response_timeout = connection.response_timeout;
  RigDevices d;
  auto acquisition =
      std::make_unique<CanAcquisition>(OpenCanTransport(connection.acquisition, /*listen=*/true), connection.can);
  auto controller = std::make_unique<ModbusController>(modbus);
  d.description = controller->Describe() + " + " + connection.acquisition;
  d.acquisition = std::move(acquisition);
  d.controller = std::move(controller);
  return d;
}

RigDevices ConnectRig(const RigConnection& connection, std::span<const RigDeviceFactory* const> factories) {
  std::vector<std::string> accepted;
  for (const RigDeviceFactory* factory : factories) {
    if (factory->Accepts(connection)) return factory->Connect(connection);
    accepted.push_back(factory->Accepted());
  }
  throw std::invalid_argument(fmt::format("rig '{}': no kind of rig takes it (known: {})", connection.controller,
                                          fmt::join(accepted, "; ")));
}

}  // namespace strut::daq
