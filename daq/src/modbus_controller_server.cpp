// ModbusControllerServer: a ControllerBackend served over Modbus TCP (libmodbus server side).
// One thread: select() over the listening socket and the clients, one request at a time, so the
// register mapping and the backend are only ever touched from here.
#include <arpa/inet.h>
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <spdlog/spdlog.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "strut/daq/modbus_controller.h"

namespace strut::daq {

namespace reg = registers;
using Clock = std::chrono::steady_clock;

bool ModbusServerOptions::IsValid(std::string* error) const {
  auto fail = [&](const std::string& why) {
    if (error) *error = why;
    return false;
  };
  in_addr address{};
  if (inet_pton(AF_INET, host.c_str(), &address) != 1)
    return fail("host '" + host + "' is not an IPv4 address (the server binds one address, e.g. 127.0.0.1)");
  if (port < 0 || port > 65535) return fail("port " + std::to_string(port) + " is not in 0..65535");
  if (tick < std::chrono::milliseconds(1) || tick > std::chrono::milliseconds(1000))
    return fail("tick " + std::to_string(tick.count()) + " ms is not in 1..1000 ms");
  if (byte_timeout < std::chrono::milliseconds(1))
    return fail("byte_timeout " + std::to_string(byte_timeout.count()) + " ms is not positive");
  if (max_connections < 1 || max_connections > 64)
    return fail("max_connections " + std::to_string(max_connections) + " is not in 1..64");
  return true;
}

class ModbusControllerServer::Impl {
 public:
  modbus_t* ctx = nullptr;
  modbus_mapping_t* map = nullptr;
  int listen_fd = -1;
  std::vector<int> clients;

  // Controller state the server owns (the rest is the backend's).
  std::uint16_t applied_sequence = 0;
  std::uint16_t heartbeat = 0;
  std::uint16_t server_faults = 0;  //!< fault_bits the server raised (kHeartbeatLost, kDevice)
  bool watchdog_tripped = false;
  Clock::time_point last_beat = Clock::now();
  Clock::time_point start = Clock::now();  //!< of the loop: the status time when the backend fails
  std::array<std::uint8_t, MODBUS_TCP_MAX_ADU_LENGTH> query{};  //!< the request being answered

  ~Impl() {
    for (int fd : clients) close(fd);
    if (listen_fd >= 0) close(listen_fd);
    if (map) modbus_mapping_free(map);
    if (ctx) modbus_free(ctx);
  }
};

ModbusControllerServer::ModbusControllerServer(ControllerBackend& backend, ModbusServerOptions options)
    : backend_(backend), options_(std::move(options)), impl_(std::make_unique<Impl>()) {
  std::string error;
  if (!options_.IsValid(&error)) throw std::invalid_argument("Modbus server options: " + error);
  const std::string where = options_.host + ":" + std::to_string(options_.port);
  impl_->ctx = modbus_new_tcp(options_.host.c_str(), options_.port);
  if (impl_->ctx == nullptr)
    throw DeviceError(DeviceError::Kind::kConnection, "modbus-tcp server " + where, "create context", "", errno,
                      modbus_strerror(errno));
  const auto us = std::chrono::duration_cast<std::chrono::microseconds>(options_.byte_timeout).count();
  modbus_set_byte_timeout(impl_->ctx, static_cast<uint32_t>(us / 1000000), static_cast<uint32_t>(us % 1000000));
  // The first byte is there when select() says so; the indication timeout only bounds a read
  // that select() woke up for in vain.
  modbus_set_indication_timeout(impl_->ctx, static_cast<uint32_t>(us / 1000000), static_cast<uint32_t>(us % 1000000));
  impl_->map = modbus_mapping_new(0, 0, reg::holding::kCount, reg::input::kCount);
  if (impl_->map == nullptr)
    throw DeviceError(DeviceError::Kind::kConnection, "modbus-tcp server " + where, "allocate registers", "", errno,
                      modbus_strerror(errno));
  // The backlog is larger than max_connections: a burst of connects must not wait for SYN
  // retransmissions while the loop catches up (those beyond max_connections are closed at once).
  impl_->listen_fd = modbus_tcp_listen(impl_->ctx, 4 * options_.max_connections);
  if (impl_->listen_fd < 0) {
    const int e = errno;
    throw DeviceError(DeviceError::Kind::kConnection, "modbus-tcp server " + where, "listen", "", e, modbus_strerror(e));
  }
  sockaddr_in bound{};
  socklen_t length = sizeof bound;
  if (getsockname(impl_->listen_fd, reinterpret_cast<sockaddr*>(&bound), &length) == 0) port_ = ntohs(bound.sin_port);
  thread_ = std::thread([this] { Loop(); });
  spdlog::debug("Modbus controller server listening on {}", endpoint().ToString());
}

ModbusControllerServer::~ModbusControllerServer() { Stop(); }

void ModbusControllerServer::Stop() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
  for (int fd : impl_->clients) close(fd);
  impl_->clients.clear();
  if (impl_->listen_fd >= 0) close(impl_->listen_fd);
  impl_->listen_fd = -1;
}

namespace {

std::uint16_t Be16(const std::uint8_t* p) { return static_cast<std::uint16_t>((p[0] << 8) | p[1]); }

//! The holding registers one request writes: address and values (count 0: not a write).
struct Write {
  int address = 0;
  std::vector<std::uint16_t> values;
};

Write WriteOf(const std::uint8_t* query, int length, int header) {
  Write w;
  const std::uint8_t function = query[header];
  if (function == MODBUS_FC_WRITE_SINGLE_REGISTER && length >= header + 5) {
    w.address = Be16(query + header + 1);
    w.values = {Be16(query + header + 3)};
  } else if (function == MODBUS_FC_WRITE_MULTIPLE_REGISTERS && length >= header + 6) {
    w.address = Be16(query + header + 1);
    const int count = Be16(query + header + 3);
    const int bytes = query[header + 5];
    // A malformed request is left to modbus_reply, which answers it with an exception.
    if (count < 1 || count > MODBUS_MAX_WRITE_REGISTERS || bytes != 2 * count || length < header + 6 + bytes)
      return Write{};
    for (int i = 0; i < count; ++i) w.values.push_back(Be16(query + header + 6 + 2 * i));
  }
  return w;
}

//! A write refused, with the Modbus exception it is answered with.
struct Refused {
  reg::Refusal refusal;
  unsigned exception = 0;
};

//! How the backend's answer to a write touching `address` is refused: its reason as a refused state,
//! a throw as a device failure; nullopt when `ask` accepts.
template <typename Ask>
std::optional<Refused> BackendRefusal(std::uint16_t address, Ask ask) {
  std::optional<std::string> reason;
  try {
    reason = ask();
  } catch (const std::exception& e) {  // the caller's backend: answered as a device failure
    return Refused{{reg::RefusalCode::kDeviceFailure, address, e.what()}, MODBUS_EXCEPTION_SLAVE_OR_SERVER_FAILURE};
  }
  if (reason) return Refused{{reg::RefusalCode::kStateRefused, address, *reason}, MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE};
  return std::nullopt;
}

}  // namespace

void ModbusControllerServer::RefreshStatus() {
  Impl& s = *impl_;
  ControllerStatus status;
  // The backend is the caller's code behind an interface (a simulated plant, a device): whatever
  // it throws is carried to the client as the device fault bit and to the log, and the server
  // goes on answering, so that the client sees the fault instead of a vanished server.
  try {
    status = backend_.Status();
  } catch (const std::exception& e) {
    if (!(s.server_faults & fault_bits::kDevice)) spdlog::error("controller backend failed: {}", e.what());
    s.server_faults |= fault_bits::kDevice;
    status.state = ControllerState::kFaulted;
    status.time_ms = static_cast<std::uint32_t>(
        std::chrono::duration_cast<std::chrono::milliseconds>(Clock::now() - s.start).count());
  }
  status.applied_sequence = s.applied_sequence;
  status.heartbeat = s.heartbeat;
  status.fault_word |= s.server_faults;
  if (s.map->tab_registers[reg::holding::kWatchdogMs] != 0) status.status_word |= status_bits::kWatchdogEnabled;
  const reg::StatusBlock block = reg::EncodeStatus(status);
  std::copy(block.begin(), block.end(), s.map->tab_input_registers + reg::input::kStatusBlock);
}

void ModbusControllerServer::Refuse(const std::uint8_t* query, const registers::Refusal& refusal, unsigned exception) {
  Impl& s = *impl_;
  spdlog::debug("Modbus controller server refuses a write: {}", refusal.message);
  const reg::RefusalBlock block = reg::EncodeRefusal(refusal);
  std::copy(block.begin(), block.end(), s.map->tab_input_registers + reg::input::kRefusalBlock);
  modbus_reply_exception(s.ctx, query, exception);
  ++refusals_;
}

void ModbusControllerServer::Tick() {
  Impl& s = *impl_;
  ++s.heartbeat;
  const std::uint16_t watchdog = s.map->tab_registers[reg::holding::kWatchdogMs];
  if (watchdog != 0 && !s.watchdog_tripped && Clock::now() - s.last_beat > std::chrono::milliseconds(watchdog)) {
    s.watchdog_tripped = true;
    s.server_faults |= fault_bits::kHeartbeatLost;
    spdlog::warn("Modbus controller server: no client heartbeat for {} ms; stopping", watchdog);
    try {
      backend_.Execute(ControllerCommand::kStop);
    } catch (const std::exception& e) {  // the caller's backend: see RefreshStatus
      spdlog::error("controller backend failed to stop: {}", e.what());
    }
  }
  RefreshStatus();
}

void ModbusControllerServer::HandleWrite(const std::uint8_t* query, int length, int address,
                                         std::span<const std::uint16_t> values) {
  Impl& s = *impl_;
  const int end = address + static_cast<int>(values.size());
  if (end > reg::holding::kCount) {
    modbus_reply(s.ctx, query, length, s.map);  // illegal data address
    return;
  }
  auto touches = [&](int a) { return a >= address && a < end; };
  std::array<std::uint16_t, reg::holding::kCount> proposed{};
  std::copy(s.map->tab_registers, s.map->tab_registers + reg::holding::kCount, proposed.begin());
  std::copy(values.begin(), values.end(), proposed.begin() + address);

  std::optional<ControllerCommand> command;
  if (touches(reg::holding::kCommand)) {
    const auto decoded = reg::DecodeCommand(proposed[reg::holding::kCommand]);
    if (!decoded.ok()) return Refuse(query, decoded.refusal, MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE);
    command = *decoded.value;
  }
  const std::uint16_t sequence = proposed[reg::holding::kSequence];
  if (touches(reg::holding::kSequence) && sequence != s.applied_sequence) {
    const auto decoded = reg::DecodeSetPoint(
        std::span<const std::uint16_t>(proposed.data() + reg::holding::kSetPointBlock, reg::holding::kSetPointCount));
    if (!decoded.ok()) return Refuse(query, decoded.refusal, MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE);
    if (const auto refused = BackendRefusal(reg::holding::kSequence, [&] { return backend_.Apply(*decoded.value); }))
      return Refuse(query, refused->refusal, refused->exception);
    // Applied: the block stays even if a command in the same request is refused below.
    std::copy(proposed.begin() + reg::holding::kSetPointBlock,
              proposed.begin() + reg::holding::kSetPointBlock + reg::holding::kSetPointCount,
              s.map->tab_registers + reg::holding::kSetPointBlock);
    s.applied_sequence = sequence;
  }
  if (command) {
    if (const auto refused = BackendRefusal(reg::holding::kCommand, [&] { return backend_.Execute(*command); }))
      return Refuse(query, refused->refusal, refused->exception);
    if (*command == ControllerCommand::kResetFaults) {
      s.server_faults = 0;
      s.watchdog_tripped = false;
      s.last_beat = Clock::now();
    }
  }
  if ((touches(reg::holding::kClientHeartbeat) &&
       proposed[reg::holding::kClientHeartbeat] != s.map->tab_registers[reg::holding::kClientHeartbeat]) ||
      touches(reg::holding::kWatchdogMs))
    s.last_beat = Clock::now();
  modbus_reply(s.ctx, query, length, s.map);
}

void ModbusControllerServer::Accept() {
  Impl& s = *impl_;
  const int fd = accept4(s.listen_fd, nullptr, nullptr, SOCK_CLOEXEC);
  if (fd < 0) return;
  if (static_cast<int>(s.clients.size()) >= options_.max_connections) {
    spdlog::warn("Modbus controller server: refusing a connection beyond {}", options_.max_connections);
    close(fd);
  } else {
    s.clients.push_back(fd);
  }
}

bool ModbusControllerServer::Serve(int fd) {
  Impl& s = *impl_;
  std::uint8_t* query = s.query.data();
  modbus_set_socket(s.ctx, fd);
  const int length = modbus_receive(s.ctx, query);
  if (length < 0) return false;  // closed by the peer, or a request cut off mid-way (byte timeout)
  const int header = modbus_get_header_length(s.ctx);
  if (length <= header) return true;
  ++requests_;
  RefreshStatus();
  const std::uint8_t function = query[header];
  if (function == MODBUS_FC_READ_HOLDING_REGISTERS || function == MODBUS_FC_READ_INPUT_REGISTERS) {
    modbus_reply(s.ctx, query, length, s.map);
  } else if (function == MODBUS_FC_WRITE_SINGLE_REGISTER || function == MODBUS_FC_WRITE_MULTIPLE_REGISTERS) {
    const Write w = WriteOf(query, length, header);
    if (w.values.empty())
      modbus_reply(s.ctx, query, length, s.map);  // malformed: libmodbus answers the exception
    else
      HandleWrite(query, length, w.address, w.values);
    RefreshStatus();
  } else {
    modbus_reply_exception(s.ctx, query, MODBUS_EXCEPTION_ILLEGAL_FUNCTION);
  }
  return true;
}

void ModbusControllerServer::Loop() {
  Impl& s = *impl_;
  s.start = Clock::now();
  auto next_tick = s.start;
  while (!stop_) {
    fd_set readable;
    FD_ZERO(&readable);
    FD_SET(s.listen_fd, &readable);
    int highest = s.listen_fd;
    for (int fd : s.clients) {
      FD_SET(fd, &readable);
      highest = std::max(highest, fd);
    }
    const auto wait = std::max(Clock::duration::zero(), next_tick - Clock::now());
    timeval tv{0, static_cast<suseconds_t>(std::chrono::duration_cast<std::chrono::microseconds>(wait).count())};
    const int ready = select(highest + 1, &readable, nullptr, nullptr, &tv);
    if (ready < 0 && errno != EINTR) {
      spdlog::error("Modbus controller server: select: {}", std::strerror(errno));
      break;
    }
    if (Clock::now() >= next_tick) {
      Tick();
      next_tick += options_.tick;
      if (next_tick < Clock::now()) next_tick = Clock::now() + options_.tick;  // fell behind: no burst
    }
    if (ready <= 0) continue;
    if (FD_ISSET(s.listen_fd, &readable)) Accept();
    for (auto it = s.clients.begin(); it != s.clients.end();) {
      if (FD_ISSET(*it, &readable) && !Serve(*it)) {
        close(*it);
        it = s.clients.erase(it);
      } else {
        ++it;
      }
    }
  }
  modbus_set_socket(s.ctx, -1);
}

}  // namespace strut::daq
