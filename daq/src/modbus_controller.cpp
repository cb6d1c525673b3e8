// ModbusController: the actuator controller over Modbus TCP, client side (libmodbus).
// One I/O thread owns the libmodbus context; see docs/register-map.md for the rules.
#include "strut/daq/modbus_controller.h"

#include <modbus/modbus.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <future>
#include <stdexcept>

namespace strut::daq {

namespace reg = registers;
using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

std::string ModbusEndpoint::ToString() const {
  const bool v6 = host.find(':') != std::string::npos;
  return "modbus-tcp://" + (v6 ? "[" + host + "]" : host) + ":" + std::to_string(port);
}

ModbusEndpoint ParseModbusEndpoint(std::string_view text) {
  std::string_view rest = text;
  constexpr std::string_view kScheme = "modbus-tcp://";
  if (rest.substr(0, kScheme.size()) == kScheme) rest.remove_prefix(kScheme.size());
  const auto bad = [&](const std::string& why) {
    return std::invalid_argument("Modbus endpoint '" + std::string(text) + "': " + why +
                                 " (expected HOST:PORT or modbus-tcp://HOST:PORT)");
  };
  std::string_view host, port;
  if (!rest.empty() && rest.front() == '[') {
    const auto close = rest.find(']');
    if (close == std::string_view::npos || close + 1 >= rest.size() || rest[close + 1] != ':')
      throw bad("an IPv6 address needs [ADDRESS]:PORT");
    host = rest.substr(1, close - 1);
    port = rest.substr(close + 2);
  } else {
    const auto colon = rest.rfind(':');
    if (colon == std::string_view::npos) throw bad("no port");
    host = rest.substr(0, colon);
    port = rest.substr(colon + 1);
  }
  if (host.empty()) throw bad("no host");
  int value = 0;
  const auto [end, ec] = std::from_chars(port.data(), port.data() + port.size(), value);
  if (ec != std::errc() || end != port.data() + port.size() || value < 1 || value > 65535)
    throw bad("port '" + std::string(port) + "' is not a number in 1..65535");
  return ModbusEndpoint{std::string(host), value};
}

bool ModbusControllerOptions::IsValid(std::string* error) const {
  auto fail = [&](const std::string& why) {
    if (error) *error = why;
    return false;
  };
  if (endpoint.host.empty()) return fail("endpoint: no host");
  if (endpoint.port < 1 || endpoint.port > 65535)
    return fail("endpoint: port " + std::to_string(endpoint.port) + " is not in 1..65535");
  if (unit_id < 0 || unit_id > 247) return fail("unit_id " + std::to_string(unit_id) + " is not in 0..247");
  if (response_timeout < milliseconds(1) || response_timeout > milliseconds(60000))
    return fail("response_timeout " + std::to_string(response_timeout.count()) + " ms is not in 1..60000 ms");
  if (byte_timeout < milliseconds(1) || byte_timeout > milliseconds(60000))
    return fail("byte_timeout " + std::to_string(byte_timeout.count()) + " ms is not in 1..60000 ms");
  if (reconnect_initial < milliseconds(1))
    return fail("reconnect_initial " + std::to_string(reconnect_initial.count()) + " ms is not positive");
  if (reconnect_max < reconnect_initial)
    return fail("reconnect_max " + std::to_string(reconnect_max.count()) + " ms is below reconnect_initial " +
                std::to_string(reconnect_initial.count()) + " ms");
  return true;
}

namespace {

std::string Range(const char* kind, std::uint16_t address, std::uint16_t count) {
  std::string text = std::string(kind) + " registers " + std::to_string(address) + "-" +
                     std::to_string(address + count - 1);
  return text;
}

void SetTimeout(modbus_t* ctx, milliseconds t, int (*set)(modbus_t*, uint32_t, uint32_t)) {
  const auto us = std::chrono::duration_cast<std::chrono::microseconds>(t).count();
  set(ctx, static_cast<uint32_t>(us / 1000000), static_cast<uint32_t>(us % 1000000));
}

}  // namespace

//! The libmodbus context and the connection state. Touched by the I/O thread only, except the
//! stats (under their own mutex).
class ModbusController::Connection {
 public:
  explicit Connection(const ModbusControllerOptions& options)
      : options_(options), device_(options.endpoint.ToString()), backoff_(options.reconnect_initial) {}
  ~Connection() { Close(); }

  bool connected() const { return ctx_ != nullptr; }
  Clock::time_point next_attempt() const { return next_attempt_; }
  const std::string& device() const { return device_; }
  modbus_t* ctx() { return ctx_; }
  //! The sequence number of the next set-point: one after the last one this connection wrote,
  //! or after the one the controller had applied when it connected (0 is skipped).
  std::uint16_t NextSequence() {
    sequence_ = static_cast<std::uint16_t>(sequence_ + 1);
    if (sequence_ == 0) sequence_ = 1;
    return sequence_;
  }

  //! Connected on return, or throws kConnection (and the next attempt is scheduled).
  void Ensure() {
    if (connected()) {
      // An answer that arrived late after a timeout must not be taken for the next answer.
      if (dirty_) Flush();
      dirty_ = false;
      return;
    }
    const auto now = Clock::now();
    if (now < next_attempt_) {
      const auto wait = std::chrono::duration_cast<milliseconds>(next_attempt_ - now).count();
      throw DeviceError(DeviceError::Kind::kConnection, device_, "connect", "", ENOTCONN,
                        "not connected (" + last_error() + "); next attempt in " + std::to_string(wait) + " ms");
    }
    Connect();
  }

  //! One connect attempt. Throws kConnection on failure.
  void Connect() {
    Close();
    {
      std::lock_guard lock(stats_mutex_);
      ++stats_.connect_attempts;
    }
    const std::string port = std::to_string(options_.endpoint.port);
    modbus_t* ctx = modbus_new_tcp_pi(options_.endpoint.host.c_str(), port.c_str());
    if (ctx == nullptr) ConnectFailed(errno, "cannot create a libmodbus context");
    SetTimeout(ctx, options_.response_timeout, modbus_set_response_timeout);
    SetTimeout(ctx, options_.byte_timeout, modbus_set_byte_timeout);
    modbus_set_slave(ctx, options_.unit_id);
    if (modbus_connect(ctx) == -1) {
      const int e = errno;
      modbus_free(ctx);
      ConnectFailed(e, modbus_strerror(e));
    }
    ctx_ = ctx;
    // A new client continues after the sequence the controller has applied, so that its first
    // set-point is never mistaken for the one already in force.
    std::uint16_t applied = 0;
    if (modbus_read_input_registers(ctx_, reg::input::kAppliedSequence, 1, &applied) != 1) {
      const int e = errno;
      Close();
      ConnectFailed(e, std::string("reading the applied sequence: ") + modbus_strerror(e));
    }
    sequence_ = applied;
    backoff_ = options_.reconnect_initial;
    std::lock_guard lock(stats_mutex_);
    stats_.connected = true;
    stats_.next_backoff = backoff_;
    spdlog::debug("{}: connected", device_);
  }

  void Close() {
    if (ctx_ == nullptr) return;
    modbus_close(ctx_);
    modbus_free(ctx_);
    ctx_ = nullptr;
    std::lock_guard lock(stats_mutex_);
    stats_.connected = false;
  }

  //! Turns the failure of a libmodbus call (errno) into a DeviceError and recovers the
  //! connection: a timeout or a garbled answer flushes it, anything else closes it (the I/O
  //! thread then reconnects with backoff). An exception response leaves it as it is.
  [[noreturn]] void Fail(const std::string& operation, const std::string& item, int e,
                         const std::string& extra = "") {
    std::string detail = modbus_strerror(e);
    if (!extra.empty()) detail += ": " + extra;
    DeviceError::Kind kind;
    if (e == ETIMEDOUT) {
      kind = DeviceError::Kind::kTimeout;
      detail += " (response timeout " + std::to_string(options_.response_timeout.count()) + " ms, byte timeout " +
                std::to_string(options_.byte_timeout.count()) + " ms)";
      Flush();
      dirty_ = true;
      std::lock_guard lock(stats_mutex_);
      ++stats_.timeouts;
    } else if (e >= EMBXILFUN && e <= EMBXGTAR) {
      kind = DeviceError::Kind::kRefused;
    } else if (e == EMBBADCRC || e == EMBBADDATA || e == EMBBADEXC || e == EMBUNKEXC || e == EMBMDATA ||
               e == EMBBADSLAVE) {
      // A garbled or mismatched answer (e.g. a late one, transaction id of an earlier request):
      // flushing may not catch what is still under way, so start over on a fresh connection.
      kind = DeviceError::Kind::kProtocol;
      Flush();
      Close();
      next_attempt_ = Clock::now();
    } else {
      kind = DeviceError::Kind::kConnection;
      Close();
      next_attempt_ = Clock::now();  // the first reconnect right away, then with backoff
    }
    DeviceError error(kind, device_, operation, item, e, detail);
    RecordError(error.what());
    throw error;
  }

  void Flush() {
    if (ctx_ == nullptr) return;
    modbus_flush(ctx_);
    std::lock_guard lock(stats_mutex_);
    ++stats_.flushes;
  }

  void RecordError(const std::string& what) {
    std::lock_guard lock(stats_mutex_);
    stats_.last_error = what;
  }

  ModbusConnectionStats stats() const {
    std::lock_guard lock(stats_mutex_);
    return stats_;
  }

 private:
  [[noreturn]] void ConnectFailed(int e, const std::string& detail) {
    next_attempt_ = Clock::now() + backoff_;
    const milliseconds scheduled = backoff_;
    backoff_ = std::min(backoff_ * 2, options_.reconnect_max);
    DeviceError error(DeviceError::Kind::kConnection, device_, "connect", "", e,
                      detail + "; next attempt in " + std::to_string(scheduled.count()) + " ms");
    std::lock_guard lock(stats_mutex_);
    ++stats_.connect_failures;
    stats_.connected = false;
    stats_.next_backoff = scheduled;
    if (stats_.backoffs.size() < 64) stats_.backoffs.push_back(scheduled);
    stats_.last_error = error.what();
    throw error;
  }

  std::string last_error() const {
    std::lock_guard lock(stats_mutex_);
    return stats_.last_error.empty() ? "no connection yet" : "last error: " + stats_.last_error;
  }

  const ModbusControllerOptions& options_;
  const std::string device_;
  modbus_t* ctx_ = nullptr;
  Clock::time_point next_attempt_ = Clock::now();
  milliseconds backoff_;
  std::uint16_t sequence_ = 0;
  bool dirty_ = false;  //!< the last request timed out: flush again before the next one
  mutable std::mutex stats_mutex_;
  ModbusConnectionStats stats_;
};

struct ModbusController::Pending {
  std::string operation;
  Job job;
  std::promise<void> done;
  bool started = false;  //!< under mutex_: the I/O thread has taken it
};

ModbusController::ModbusController(ModbusControllerOptions options) : options_(std::move(options)) {
  std::string error;
  if (!options_.IsValid(&error)) throw std::invalid_argument("Modbus controller options: " + error);
  connection_ = std::make_unique<Connection>(options_);
  io_thread_ = std::thread([this] { IoLoop(); });
}

ModbusController::~ModbusController() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  io_thread_.join();
}

std::string ModbusController::Describe() const { return options_.endpoint.ToString(); }

ModbusConnectionStats ModbusController::stats() const { return connection_->stats(); }

void ModbusController::IoLoop() {
  std::unique_lock lock(mutex_);
  while (!stopping_) {
    if (!queue_.empty()) {
      std::shared_ptr<Pending> pending = std::move(queue_.front());
      queue_.pop_front();
      pending->started = true;
      lock.unlock();
      try {
        pending->job(*connection_);
        pending->done.set_value();
      } catch (...) {  // the I/O thread's boundary: the caller waiting on `done` gets the exception
        pending->done.set_exception(std::current_exception());
      }
      lock.lock();
      continue;
    }
    if (!connection_->connected()) {
      if (Clock::now() >= connection_->next_attempt()) {
        lock.unlock();
        try {
          connection_->Connect();
        } catch (const DeviceError& e) {
          spdlog::debug("{}", e.what());
        }
        lock.lock();
        continue;
      }
      wake_.wait_until(lock, connection_->next_attempt());
    } else {
      wake_.wait(lock);
    }
  }
  // Calls still queued at shutdown get an answer rather than a broken promise.
  for (auto& pending : queue_)
    pending->done.set_exception(std::make_exception_ptr(DeviceError(
        DeviceError::Kind::kConnection, Describe(), pending->operation, "", 0, "the controller client is shutting down")));
  queue_.clear();
  connection_->Close();
}

void ModbusController::Submit(const std::string& operation, Job job) {
  auto pending = std::make_shared<Pending>();
  pending->operation = operation;
  pending->job = std::move(job);
  std::future<void> done = pending->done.get_future();
  {
    std::lock_guard lock(mutex_);
    queue_.push_back(pending);
  }
  wake_.notify_all();
  // A call still queued after its budget (many calls ahead of it, each up to its timeouts) is
  // withdrawn and fails with kTimeout. A call the I/O thread has started is waited for: the
  // job refers to the caller's variables, and libmodbus's timeouts bound it.
  const auto budget = 2 * (options_.response_timeout + 4 * options_.byte_timeout) + milliseconds(1000);
  if (done.wait_for(budget) != std::future_status::ready) {
    std::unique_lock lock(mutex_);
    if (!pending->started) {
      queue_.erase(std::find(queue_.begin(), queue_.end(), pending));
      throw DeviceError(DeviceError::Kind::kTimeout, Describe(), operation, "", ETIMEDOUT,
                        "still queued behind other calls after " + std::to_string(budget.count()) + " ms");
    }
    lock.unlock();
    done.wait();
  }
  done.get();
}

namespace {

//! The controller's reason for the last refusal (input registers 16-49), or "" when unreadable.
std::string RefusalReason(modbus_t* ctx) {
  reg::RefusalBlock block{};
  if (modbus_read_input_registers(ctx, reg::input::kRefusalBlock, reg::input::kRefusalCount, block.data()) !=
      reg::input::kRefusalCount)
    return "";
  const reg::Refusal refusal = reg::DecodeRefusal(block);
  if (refusal.code == reg::RefusalCode::kNone) return "";
  std::string text = refusal.message.empty() ? std::string(reg::ToString(refusal.code)) : refusal.message;
  return "controller says: " + text + " [" + std::string(reg::ToString(refusal.code)) + ", " +
         reg::HoldingName(refusal.address) + "]";
}

//! After a failed write: the refusal reason when the controller answered with an exception.
std::string ReasonFor(modbus_t* ctx, int e) {
  if (ctx == nullptr || (e != EMBXILVAL && e != EMBXSFAIL)) return "";
  return RefusalReason(ctx);
}

//! A whole register block read in one request with `read` (modbus_read_registers or
//! modbus_read_input_registers) from `first` and decoded: a short read fails the connection with
//! `item`, a block `decode` refuses is an invalid value of the register `name` names.
template <typename Block, typename Connection, typename Read, typename Decode, typename Name>
auto ReadBlock(Connection& c, const std::string& device, const std::string& operation, const std::string& item,
               std::uint16_t first, Read read, Decode decode, Name name) {
  Block block{};
  const int count = static_cast<int>(block.size());
  const int rc = read(c.ctx(), first, count, block.data());
  if (rc != count) c.Fail(operation, item, rc == -1 ? errno : EMBBADDATA);
  const auto decoded = decode(block);
  if (!decoded.ok())
    throw DeviceError(DeviceError::Kind::kInvalidValue, device, operation, name(decoded.refusal.address), 0,
                      decoded.refusal.message);
  return *decoded.value;
}

}  // namespace

std::uint16_t ModbusController::WriteSetPoint(const SetPoint& set_point) {
  const std::string operation = "write set-point";
  std::string why;
  if (!set_point.IsValid(&why))
    throw DeviceError(DeviceError::Kind::kInvalidValue, Describe(), operation, "", 0, why + " (not sent)");
  std::uint16_t written = 0;
  Submit(operation, [&, set_point](Connection& c) {
    c.Ensure();
    const std::uint16_t sequence = c.NextSequence();
    const reg::SetPointBlock block = reg::EncodeSetPoint(set_point, sequence);
    // Float32 rounding can move a value onto the wrong side of a limit: check what is sent.
    const auto check = reg::DecodeSetPoint(block);
    if (!check.ok())
      throw DeviceError(DeviceError::Kind::kInvalidValue, Describe(), operation, reg::HoldingName(check.refusal.address),
                        0, check.refusal.message + " (after rounding to float32; not sent)");
    const std::string item = Range("holding", reg::holding::kSetPointBlock, reg::holding::kSetPointCount) +
                             " (set-point block, sequence " + std::to_string(sequence) + ")";
    const int rc = modbus_write_registers(c.ctx(), reg::holding::kSetPointBlock, reg::holding::kSetPointCount, block.data());
    if (rc != reg::holding::kSetPointCount) {
      const int e = rc == -1 ? errno : EMBBADDATA;
      c.Fail(operation, item, e, ReasonFor(c.ctx(), e));
    }
    written = sequence;
  });
  return written;
}

SetPoint ModbusController::ReadSetPoint() {
  const std::string operation = "read set-point";
  SetPoint result;
  Submit(operation, [&](Connection& c) {
    c.Ensure();
    result = ReadBlock<reg::SetPointBlock>(
        c, Describe(), operation,
        Range("holding", reg::holding::kSetPointBlock, reg::holding::kSetPointCount) + " (set-point block)",
        reg::holding::kSetPointBlock, modbus_read_registers, reg::DecodeSetPoint, reg::HoldingName);
  });
  return result;
}

void ModbusController::Command(ControllerCommand command) {
  const std::string operation = "command " + std::string(ToString(command));
  Submit(operation, [&, command](Connection& c) {
    c.Ensure();
    if (modbus_write_register(c.ctx(), reg::holding::kCommand, static_cast<std::uint16_t>(command)) != 1) {
      const int e = errno;
      c.Fail(operation, reg::HoldingName(reg::holding::kCommand), e, ReasonFor(c.ctx(), e));
    }
  });
}

ControllerStatus ModbusController::ReadStatus() {
  const std::string operation = "read status";
  ControllerStatus result;
  Submit(operation, [&](Connection& c) {
    c.Ensure();
    result = ReadBlock<reg::StatusBlock>(
        c, Describe(), operation, Range("input", reg::input::kStatusBlock, reg::input::kStatusCount) + " (status block)",
        reg::input::kStatusBlock, modbus_read_input_registers, reg::DecodeStatus, reg::InputName);
  });
  return result;
}

void ModbusController::Heartbeat() {
  const std::string operation = "heartbeat";
  Submit(operation, [&](Connection& c) {
    c.Ensure();
    const std::uint16_t beat = static_cast<std::uint16_t>(heartbeat_ + 1);
    if (modbus_write_register(c.ctx(), reg::holding::kClientHeartbeat, beat) != 1)
      c.Fail(operation, reg::HoldingName(reg::holding::kClientHeartbeat), errno);
    heartbeat_ = beat;
  });
}

void ModbusController::SetWatchdog(std::chrono::milliseconds timeout) {
  const std::string operation = "set watchdog";
  if (timeout < milliseconds(0) || timeout > milliseconds(65535))
    throw DeviceError(DeviceError::Kind::kInvalidValue, Describe(), operation, reg::HoldingName(reg::holding::kWatchdogMs),
                      0, std::to_string(timeout.count()) + " ms is not in 0..65535 ms (not sent)");
  Submit(operation, [&, timeout](Connection& c) {
    c.Ensure();
    if (modbus_write_register(c.ctx(), reg::holding::kWatchdogMs, static_cast<std::uint16_t>(timeout.count())) != 1)
      c.Fail(operation, reg::HoldingName(reg::holding::kWatchdogMs), errno);
  });
}

std::vector<std::uint16_t> ModbusController::ReadHoldingRegisters(std::uint16_t address, std::uint16_t count) {
  return ReadRegisters(false, address, count);
}

std::vector<std::uint16_t> ModbusController::ReadInputRegisters(std::uint16_t address, std::uint16_t count) {
  return ReadRegisters(true, address, count);
}

std::vector<std::uint16_t> ModbusController::ReadRegisters(bool input, std::uint16_t address, std::uint16_t count) {
  const std::string operation = "read";
  if (count < 1 || count > MODBUS_MAX_READ_REGISTERS)
    throw DeviceError(DeviceError::Kind::kInvalidValue, Describe(), operation, "", 0,
                      "count " + std::to_string(count) + " is not in 1..125");
  std::vector<std::uint16_t> values(count);
  Submit(operation, [&](Connection& c) {
    c.Ensure();
    const int read = input ? modbus_read_input_registers(c.ctx(), address, count, values.data())
                           : modbus_read_registers(c.ctx(), address, count, values.data());
    if (read != count) c.Fail(operation, Range(input ? "input" : "holding", address, count), errno);
  });
  return values;
}

void ModbusController::WriteHoldingRegisters(std::uint16_t address, std::span<const std::uint16_t> values) {
  const std::string operation = "write";
  if (values.empty() || values.size() > MODBUS_MAX_WRITE_REGISTERS)
    throw DeviceError(DeviceError::Kind::kInvalidValue, Describe(), operation, "", 0,
                      "count " + std::to_string(values.size()) + " is not in 1..123");
  std::vector<std::uint16_t> copy(values.begin(), values.end());
  Submit(operation, [&, copy](Connection& c) {
    c.Ensure();
    const int n = static_cast<int>(copy.size());
    if (modbus_write_registers(c.ctx(), address, n, copy.data()) != n) {
      const int e = errno;
      c.Fail(operation, Range("holding", address, static_cast<std::uint16_t>(n)), e, ReasonFor(c.ctx(), e));
    }
  });
}

}  // namespace strut::daq
