// The simulated rig behind the real protocols: a SimulatedController served over Modbus TCP
// (daq::ModbusControllerServer) and its sensors streamed as CAN frames (sim::CanModule) over a
// CAN transport, paced by the simulation clock. What `strut rig serve-sim` runs, and what a
// runner or a test starts in-process (SimulatedRigFactory: the rig "sim" among the kinds of rig
// of daq/rig_devices.h). docs/simulated-rig.md, "The served rig".
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "strut/daq/can_acquisition.h"
#include "strut/daq/modbus_controller.h"
#include "strut/daq/recorder.h"
#include "strut/daq/rig_devices.h"
#include "strut/sim/can_module.h"
#include "strut/sim/clock.h"
#include "strut/sim/simulated_controller.h"
#include "strut/sim/truth.h"

namespace strut::sim {

struct RigServerOptions {
  //! Where the controller listens: loopback, port 0 (ephemeral) unless told otherwise.
  daq::ModbusServerOptions modbus;
  //! Where the acquisition module sends its frames: "udp:HOST:PORT" (or "can:IFACE" on a Linux
  //! machine with SocketCAN). Not used when a transport is handed to the constructor.
  std::string can = "udp:127.0.0.1:5000";
  bool can_fd = false;  //!< CAN FD frames (8 sample sets each) rather than classic ones (one each)
  std::uint8_t can_module = 1;
  //! Simulated seconds per wall second (> 0). How fast the machine can go: docs/simulated-rig.md.
  double speed = 1.0;
  SimulatedControllerOptions controller;
  //! False with a message naming the option.
  bool IsValid(std::string* error) const;
};

//! Figures of a running server.
struct RigServerStats {
  double simulated_seconds = 0.0;
  double wall_seconds = 0.0;       //!< since Start
  double compute_seconds = 0.0;    //!< CPU time of the plant (SimulatedControllerStats::cpu_seconds)
  double max_lateness = 0.0;       //!< wall s the stream was ever behind its schedule
  std::uint64_t sets_sent = 0;     //!< sample sets handed to the transport
  long modbus_requests = 0;
};

//! Owns the plant (SimulatedController), the Modbus server, the CAN module and the pacing thread.
//! The pacing thread advances the plant chunk by chunk, each when the wall clock reaches its end
//! (simulated time / speed), and sends its samples; the stream flows whether the rig is armed or
//! not, as a real acquisition does. Stop() (or the destructor) ends everything; a failure of the
//! plant or the transport ends the stream (error() says why) while the controller keeps answering
//! with a device fault.
class RigServer final : public daq::DeviceHost {
 public:
  //! Listens at once (DeviceError kConnection when the port is taken). `can` replaces the
  //! transport named by options.can (tests). Throws TruthError or std::invalid_argument for an
  //! invalid truth or options, DeviceError when the transport cannot be opened.
  RigServer(Truth truth, RigServerOptions options, std::unique_ptr<daq::CanTransport> can = nullptr);
  ~RigServer() override;
  RigServer(const RigServer&) = delete;
  RigServer& operator=(const RigServer&) = delete;

  //! Starts the pacing thread: simulated time runs from where it is. Idempotent.
  void Start();
  //! Stops the stream and the Modbus server; idempotent.
  void Stop();

  //! The controller's endpoint (with the port actually bound).
  daq::ModbusEndpoint modbus_endpoint() const { return modbus_->endpoint(); }
  //! What a daq::CanAcquisition needs to receive the stream (layout, channels, and the rate on the
  //! wall clock: speed x the simulated sample rate, which the receiver's timing checks need).
  daq::CanAcquisitionOptions ReceiverOptions() const;
  //! The stream's sample rate in simulated time (the truth's), Hz: the rate a recording states.
  double simulated_sample_rate() const { return controller_.sample_rate(); }
  SimulatedController& controller() { return controller_; }
  const RigServerOptions& options() const { return options_; }
  RigServerStats stats() const;
  //! Why the stream ended early (the plant or the transport failed); nullopt while it is fine.
  std::optional<std::string> error() const;

  //! Fault injection (tests, demonstrations). The controller goes away: the Modbus server closes
  //! every connection and the listening socket; the plant and the stream go on.
  void StopController();
  //! The module's frames stop reaching the bus (frozen) or reach it again; the plant and the
  //! module's sample numbering go on, so the receiver sees a stale stream, then a sequence gap.
  void FreezeStream(bool frozen) { frozen_ = frozen; }

 private:
  void Loop();

  RigServerOptions options_;
  SimulatedController controller_;
  std::atomic<bool> frozen_{false};
  std::unique_ptr<CanModule> module_;
  std::unique_ptr<daq::ModbusControllerServer> modbus_;
  std::atomic<std::uint64_t> sets_sent_{0};

  mutable std::mutex mutex_;
  std::condition_variable wake_;
  bool stop_ = false;
  std::optional<std::string> error_;
  std::unique_ptr<SimulationClock> clock_;
  double max_lateness_ = 0.0;
  std::optional<std::chrono::steady_clock::time_point> started_at_;
  std::thread thread_;
};

//! The simulated rig of a truth as a kind of rig (daq::RigDeviceFactory): the controller string
//! "sim" (with the acquisition "sim" or empty) serves the truth in this process (a RigServer on
//! an ephemeral loopback port, its frames over UDP loopback) at `speed` simulated seconds per
//! wall second, already streaming, with the drivers connected to it, as `strut rig serve-sim`
//! serves it.
class SimulatedRigFactory final : public daq::RigDeviceFactory {
 public:
  SimulatedRigFactory(Truth truth, double speed) : truth_(std::move(truth)), speed_(speed) {}
  std::string Accepted() const override;
  bool Accepts(const daq::RigConnection& connection) const override;
  daq::RigDevices Connect(const daq::RigConnection& connection) const override;

 private:
  Truth truth_;
  double speed_;
};

//! The server behind devices that SimulatedRigFactory connected; null for any other rig's.
const RigServer* ServedRig(const daq::RigDevices& devices);

}  // namespace strut::sim
