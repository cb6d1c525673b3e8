// The devices a matrix run talks to and what its session records about them, shared by
// `strut rig run` and `strut bench rig`: a rig reached over the network (Modbus TCP controller,
// CAN acquisition), or the simulated rig served in this process exactly as `strut rig serve-sim`
// serves it, behind the same drivers. The runner itself is rig::MatrixRunner.
#pragma once

#include <signal.h>

#include <chrono>
#include <memory>
#include <optional>
#include <string>

#include "strut/daq/can_acquisition.h"
#include "strut/daq/modbus_controller.h"
#include "strut/daq/recorder.h"
#include "strut/rig/safety.h"
#include "strut/sim/rig_server.h"
#include "strut/sim/truth.h"

namespace strut::tools {

//! The drivers of a run and, for the simulated rig in this process, the server behind them.
//! Declared so that the drivers go before the server they are connected to.
struct RigDevices {
  std::unique_ptr<sim::RigServer> server;  //!< null for a rig reached over the network
  std::unique_ptr<daq::CanAcquisition> acquisition;
  std::unique_ptr<daq::ModbusController> controller;
  std::string daq_spec;  //!< where the acquisition listens: "udp:HOST:PORT" or "can:IFACE"
};

//! A rig reached over the network: the controller at `endpoint`, the acquisition module's frames
//! received from `daq_spec` with `can` (layout, channels, the rate on the wire).
RigDevices ConnectRig(const daq::ModbusEndpoint& endpoint, std::chrono::milliseconds response_timeout,
                      const std::string& daq_spec, daq::CanAcquisitionOptions can);

//! The simulated rig of `truth` served in this process (sim::RigServer on an ephemeral loopback
//! port, its frames over UDP loopback) at `speed` simulated seconds per wall second, already
//! streaming, with the drivers connected to it.
RigDevices ServeSimulatedRig(const sim::Truth& truth, double speed, std::chrono::milliseconds response_timeout);

//! What a new session of a run records: the damper, the rig, the operator, the matrix (its file's
//! text or "standard"), the limits in force and, when the rig is a simulated one, the truth it
//! runs (/truth, so that a fit can be checked against it).
daq::RecordingMetadata RunMetadata(const std::string& serial, const std::string& rig, const std::string& operator_name,
                                   const std::string& matrix, const rig::SafetyConfig& safety,
                                   const std::optional<sim::Truth>& truth);

//! SIGINT and SIGTERM go to `handler` while this lives (a run, a served rig); the handlers they
//! had are restored after, also when what runs throws.
class StopSignals {
 public:
  explicit StopSignals(void (*handler)(int));
  ~StopSignals();
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;

 private:
  struct sigaction old_int_ {}, old_term_ {};
};

}  // namespace strut::tools
