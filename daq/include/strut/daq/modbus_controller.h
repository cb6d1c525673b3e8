// The actuator controller over Modbus TCP (libmodbus): the client ModbusController and the
// server ModbusControllerServer that serves any ControllerBackend. Register map, threading and
// timeout rules: docs/register-map.md.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "strut/daq/controller.h"
#include "strut/daq/controller_registers.h"
#include "strut/daq/device_error.h"

namespace strut::daq {

//! HOST:PORT of a Modbus TCP peer.
struct ModbusEndpoint {
  std::string host = "127.0.0.1";
  int port = 502;
  std::string ToString() const;  //!< "modbus-tcp://HOST:PORT"
};
//! Parses "HOST:PORT", "modbus-tcp://HOST:PORT" or "[IPV6]:PORT". Throws std::invalid_argument
//! naming the text when the port is missing or not in 1..65535.
ModbusEndpoint ParseModbusEndpoint(std::string_view text);

struct ModbusControllerOptions {
  ModbusEndpoint endpoint;
  int unit_id = 1;  //!< Modbus unit identifier (slave id), 0..247
  //! Time for the first byte of an answer (and for the TCP connect). libmodbus's default is 0.5 s.
  std::chrono::milliseconds response_timeout{500};
  //! Time between two bytes of one answer. A peer that stops mid-answer is given up after this.
  std::chrono::milliseconds byte_timeout{100};
  //! Reconnect delay after a failed connect or a lost connection; doubles after every failure up
  //! to reconnect_max, back to reconnect_initial after a success.
  std::chrono::milliseconds reconnect_initial{100};
  std::chrono::milliseconds reconnect_max{5000};
  //! False, or why (naming the option).
  bool IsValid(std::string* error) const;
};

//! Counters of the connection, for tests and status displays.
struct ModbusConnectionStats {
  bool connected = false;
  long connect_attempts = 0;
  long connect_failures = 0;
  long timeouts = 0;  //!< requests that hit the response or byte timeout (each followed by modbus_flush)
  long flushes = 0;
  std::chrono::milliseconds next_backoff{0};
  //! Every reconnect delay scheduled so far (the backoff sequence), oldest first, at most 64.
  std::vector<std::chrono::milliseconds> backoffs;
  std::string last_error;  //!< what() of the last failure, "" when none
};

//! ActuatorController over Modbus TCP. One I/O thread owns the libmodbus context (which is not
//! thread-safe): every call, from any thread, is queued to it and waits for its result, so calls
//! are served one at a time in the order they arrive. A call returns or throws DeviceError within
//! its budget: the connect time (when a reconnect is due) plus response and byte timeouts of its
//! requests. While disconnected, calls fail at once with kConnection (naming the next attempt)
//! and the I/O thread reconnects in the background with capped exponential backoff.
class ModbusController final : public ActuatorController {
 public:
  //! Throws std::invalid_argument when the options are not valid. Connects in the background.
  explicit ModbusController(ModbusControllerOptions options);
  ~ModbusController() override;
  ModbusController(const ModbusController&) = delete;
  ModbusController& operator=(const ModbusController&) = delete;

  std::uint16_t WriteSetPoint(const SetPoint& set_point) override;
  SetPoint ReadSetPoint() override;
  void Command(ControllerCommand command) override;
  ControllerStatus ReadStatus() override;
  void Heartbeat() override;
  void SetWatchdog(std::chrono::milliseconds timeout) override;
  std::string Describe() const override;

  //! Raw access for tools and tests, through the same I/O thread and error handling.
  std::vector<std::uint16_t> ReadHoldingRegisters(std::uint16_t address, std::uint16_t count);
  std::vector<std::uint16_t> ReadInputRegisters(std::uint16_t address, std::uint16_t count);
  void WriteHoldingRegisters(std::uint16_t address, std::span<const std::uint16_t> values);

  ModbusConnectionStats stats() const;
  const ModbusControllerOptions& options() const { return options_; }

 private:
  //! Holding (input false) or input registers, as the two public reads ask.
  std::vector<std::uint16_t> ReadRegisters(bool input, std::uint16_t address, std::uint16_t count);
  class Connection;
  using Job = std::function<void(Connection&)>;
  //! Runs `job` on the I/O thread and waits for it (rethrowing its DeviceError).
  void Submit(const std::string& operation, Job job);
  void IoLoop();

  ModbusControllerOptions options_;
  std::unique_ptr<Connection> connection_;  //!< touched by the I/O thread only
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  struct Pending;
  std::deque<std::shared_ptr<Pending>> queue_;
  bool stopping_ = false;
  std::uint16_t heartbeat_ = 0;  //!< I/O thread only
  std::thread io_thread_;
};

struct ModbusServerOptions {
  std::string host = "127.0.0.1";  //!< loopback unless told otherwise; "0.0.0.0" for every interface
  int port = 0;                    //!< 0: an ephemeral port (see ModbusControllerServer::port())
  //! Server loop period: status refresh, heartbeat count, watchdog check, stop flag.
  std::chrono::milliseconds tick{10};
  //! A client that stops in the middle of a request is dropped after this.
  std::chrono::milliseconds byte_timeout{500};
  int max_connections = 8;
  bool IsValid(std::string* error) const;
};

//! Serves a ControllerBackend over Modbus TCP (libmodbus server side) on its own thread. A
//! set-point is applied only when a write changes the sequence register and the block's checksum
//! and values are valid; a refused write is answered with exception 3 (illegal data value),
//! stores nothing, and leaves its reason in the refusal input registers.
class ModbusControllerServer {
 public:
  //! Listens at once. Throws DeviceError kConnection naming host and port when it cannot, and
  //! std::invalid_argument for invalid options. `backend` must outlive the server.
  ModbusControllerServer(ControllerBackend& backend, ModbusServerOptions options = {});
  ~ModbusControllerServer();
  ModbusControllerServer(const ModbusControllerServer&) = delete;
  ModbusControllerServer& operator=(const ModbusControllerServer&) = delete;

  int port() const { return port_; }
  ModbusEndpoint endpoint() const { return {options_.host, port_}; }
  //! Closes every connection and the listening socket; idempotent.
  void Stop();
  //! Requests served and refused so far.
  long requests() const { return requests_.load(); }
  long refusals() const { return refusals_.load(); }

 private:
  class Impl;
  //! The server's thread: select() over the listening socket and the clients, ticking on time.
  void Loop();
  //! The heartbeat tick: counts, trips the watchdog when the client fell silent, refreshes.
  void Tick();
  //! The status block of the input registers from the backend's status and the server's own state.
  void RefreshStatus();
  //! Takes a waiting connection, or closes it when max_connections are open.
  void Accept();
  //! Receives and answers one request on `fd`; false when the connection is gone.
  bool Serve(int fd);
  //! Validates a write of `values` at `address` against the registers it would leave, applies a
  //! committed set-point and a command, and answers (normally or with an exception).
  void HandleWrite(const std::uint8_t* query, int length, int address, std::span<const std::uint16_t> values);
  //! Records the refusal in its input registers and answers the Modbus `exception`.
  void Refuse(const std::uint8_t* query, const registers::Refusal& refusal, unsigned exception);

  ControllerBackend& backend_;
  ModbusServerOptions options_;
  int port_ = 0;
  std::unique_ptr<Impl> impl_;
  std::atomic<bool> stop_{false};
  std::atomic<long> requests_{0}, refusals_{0};
  std::thread thread_;
};

}  // namespace strut::daq
