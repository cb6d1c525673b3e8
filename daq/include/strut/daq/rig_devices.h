// The devices of a rig from connection strings, as openDAQ's addDevice(uri): a factory per kind of
// rig says which strings it takes and makes the controller and the acquisition module from them.
// daq knows the rigs reached over real transports (NetworkRigFactory: the controller over Modbus
// TCP, the acquisition module over CAN); a kind that lives elsewhere brings its own factory (the
// simulated rig's is sim::SimulatedRigFactory). The caller hands ConnectRig the factories it
// wants, so what a string can reach is decided where the program is put together, not in a
// registry.
#pragma once

#include <chrono>
#include <memory>
#include <span>
#include <string>

#include "strut/daq/acquisition.h"
#include "strut/daq/can_acquisition.h"
#include "strut/daq/controller.h"

namespace strut::daq {

//! Where a rig's devices are and how long to wait for them.
struct RigConnection {
  //! The actuator controller: "modbus-tcp://HOST:PORT", "HOST:PORT", "[IPV6]:PORT", or what
  //! another factory takes ("sim").
  std::string controller;
  //! The acquisition module: "can:IFACE" (SocketCAN), "udp:HOST:PORT" (CAN frames over UDP,
  //! listened for there), or what another factory takes (empty or "sim" with "sim").
  std::string acquisition;
  //! Time for the controller's first answer byte and for its TCP connect.
  std::chrono::milliseconds response_timeout{500};
  //! The frames, channels and rate on the wire of a CAN acquisition module (a factory that knows
  //! its module's frames, as the simulated rig's does, ignores it).
  CanAcquisitionOptions can;
};

//! What serves a rig's devices in this process (a simulated rig): kept running until the drivers
//! connected to it are gone.
class DeviceHost {
 public:
  virtual ~DeviceHost() = default;
};

//! The drivers of a rig. Declared so that the drivers go before the host they are connected to.
struct RigDevices {
  std::unique_ptr<DeviceHost> host;  //!< null for a rig reached over the network
  std::unique_ptr<AcquisitionModule> acquisition;
  std::unique_ptr<ActuatorController> controller;
  //! The rig in words, for a session's `rig`: "CONTROLLER + ACQUISITION" for a rig on the network.
  std::string description;
};

//! One kind of rig.
class RigDeviceFactory {
 public:
  virtual ~RigDeviceFactory() = default;
  //! The connection strings it takes, in words, for the error when no factory takes a connection.
  virtual std::string Accepted() const = 0;
  virtual bool Accepts(const RigConnection& connection) const = 0;
  //! Opens the devices. Throws DeviceError or std::invalid_argument naming the connection string
  //! that is wrong or cannot be reached.
  virtual RigDevices Connect(const RigConnection& connection) const = 0;
};

//! A rig on the network: the controller at a Modbus TCP endpoint (ModbusController, connecting in
//! the background), the acquisition module's CAN frames received from "can:IFACE" or
//! "udp:HOST:PORT" (CanAcquisition with RigConnection::can). Takes a controller string with the
//! modbus-tcp:// scheme or without a scheme (HOST:PORT).
class NetworkRigFactory final : public RigDeviceFactory {
 public:
  std::string Accepted() const override;
  bool Accepts(const RigConnection& connection) const override;
  RigDevices Connect(const RigConnection& connection) const override;
};

//! The devices of `connection` from the first of `factories` that accepts it. Throws
//! std::invalid_argument naming the controller string and what each factory takes when none does.
RigDevices ConnectRig(const RigConnection& connection, std::span<const RigDeviceFactory* const> factories);

}  // namespace strut::daq
