// The simulated rig behind the real protocols (rig_server.h).
#include "strut/sim/rig_server.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <fmt/format.h>
#include <stdexcept>

namespace strut::sim {

bool RigServerOptions::IsValid(std::string* error) const {
  const auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  std::string why;
  if (!modbus.IsValid(&why)) return fail("modbus: " + why);
  if (!std::isfinite(speed) || speed <= 0 || speed > 1e4)
    return fail(fmt::format("speed must be in (0, 10000] simulated seconds per wall second, got {}", speed));
  if (can_module > 63) return fail(fmt::format("can_module must be 0..63, got {}", can_module));
  if (!controller.IsValid(&why)) return fail("controller: " + why);
  return true;
}

namespace {
RigServerOptions Checked(RigServerOptions options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument("simulated rig server: " + error);
  return options;
}
//! The module's transport with a gate: while frozen, frames are dropped on the way out, so the
//! module goes on numbering its sample sets and the receiver sees a stale stream, then a gap.
class GatedTransport final : public daq::CanTransport {
 public:
  GatedTransport(std::unique_ptr<daq::CanTransport> inner, const std::atomic<bool>& frozen)
      : inner_(std::move(inner)), frozen_(frozen) {}
  const std::string& name() const override { return inner_->name(); }
  void Send(std::span<const daq::CanFrame> frames, std::chrono::nanoseconds timeout) override {
    if (!frozen_) inner_->Send(frames, timeout);
  }
  std::size_t Receive(std::span<daq::CanFrame> frames, std::chrono::nanoseconds timeout) override {
    return inner_->Receive(frames, timeout);
  }
  void Flush() override { inner_->Flush(); }
  daq::CanTransportCounters counters() const override { return inner_->counters(); }

 private:
  std::unique_ptr<daq::CanTransport> inner_;
  const std::atomic<bool>& frozen_;
};
}  // namespace

RigServer::RigServer(Truth truth, RigServerOptions options, std::unique_ptr<daq::CanTransport> can)
    : options_(Checked(std::move(options))), controller_(std::move(truth), options_.controller) {
  if (!can) can = daq::OpenCanTransport(options_.can, /*listen=*/false, options_.can_fd);
  module_ = std::make_unique<CanModule>(std::make_unique<GatedTransport>(std::move(can), frozen_), controller_.truth().sensors, controller_.sample_rate(),
                                        options_.can_fd, options_.can_module);
  modbus_ = std::make_unique<daq::ModbusControllerServer>(controller_, options_.modbus);
  ClockOptions clock;
  clock.mode = ClockMode::kRealTime;
  clock.speed = options_.speed;
  // The clock sleeps on the condition variable, so Stop() wakes the pacing thread at once.
  clock_ = std::make_unique<SimulationClock>(clock, SimulationClock::Now{}, [this](SimulationClock::TimePoint until) {
    std::unique_lock lock(mutex_);
    wake_.wait_until(lock, until, [this] { return stop_; });
  });
}

RigServer::~RigServer() { Stop(); }

void RigServer::Start() {
  std::lock_guard lock(mutex_);
  if (thread_.joinable() || stop_) return;
  thread_ = std::thread([this] { Loop(); });
}

void RigServer::Stop() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
  modbus_->Stop();
}

void RigServer::StopController() { modbus_->Stop(); }

void RigServer::Loop() {
  // Simulated time t is due at wall time start + (t - t_start) / speed.
  const double t_start = controller_.time();
  {
    std::lock_guard lock(mutex_);
    started_at_ = std::chrono::steady_clock::now();
  }
  clock_->Start();
  const SampleSink sink = [this](const SampleBlock& block) {
    module_->Send(block);
    if (!frozen_) sets_sent_ += block.stroke.size();
  };
  double next_warning = 0.0;
  for (;;) {
    const double next = controller_.time() + controller_.chunk_seconds();
    const double late = clock_->WaitUntil(next - t_start);
    {
      std::lock_guard lock(mutex_);
      if (stop_) break;
      max_lateness_ = std::max(max_lateness_, late);
    }
    if (late > 1.0 && clock_->Elapsed() >= next_warning) {
      const SimulatedControllerStats s = controller_.stats();
      spdlog::warn("simulated rig: {:.1f} s behind the wall clock at speed {:g}: the plant computes {:.0f} simulated "
                   "seconds per CPU second; lower --speed",
                   late, options_.speed, s.cpu_seconds > 0 ? s.simulated_seconds / s.cpu_seconds : 0.0);
      next_warning = clock_->Elapsed() + 10.0;
    }
    try {
      controller_.Advance(next, sink);
    } catch (const std::exception& e) {
      // The streaming thread's boundary: whatever the plant or the sink threw ends the stream and
      // is kept in error_ for the caller (a throw out of this thread would end the process).
      spdlog::error("simulated rig: the stream stops: {}", e.what());
      std::lock_guard lock(mutex_);
      error_ = e.what();
      break;
    }
  }
}

daq::CanAcquisitionOptions RigServer::ReceiverOptions() const {
  daq::CanAcquisitionOptions o = module_->ReceiverOptions();
  o.sample_rate *= options_.speed;
  return o;
}

RigServerStats RigServer::stats() const {
  RigServerStats s;
  const SimulatedControllerStats c = controller_.stats();
  s.simulated_seconds = c.simulated_seconds;
  s.compute_seconds = c.cpu_seconds;
  s.sets_sent = sets_sent_.load();
  s.modbus_requests = modbus_->requests();
  std::lock_guard lock(mutex_);
  if (started_at_) s.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - *started_at_).count();
  s.max_lateness = max_lateness_;
  return s;
}

std::optional<std::string> RigServer::error() const {
  std::lock_guard lock(mutex_);
  return error_;
}

// ---------------------------------------------------------------------------------------------
// The simulated rig as a kind of rig

std::string SimulatedRigFactory::Accepted() const { return "sim (the simulated rig in this process)"; }

bool SimulatedRigFactory::Accepts(const daq::RigConnection& connection) const {
  return connection.controller == "sim" && (connection.acquisition.empty() || connection.acquisition == "sim");
}

daq::RigDevices SimulatedRigFactory::Connect(const daq::RigConnection& connection) const {
  if (!Accepts(connection))
    throw std::invalid_argument(fmt::format("rig '{}' with acquisition '{}': the simulated rig is 'sim' with its own "
                                            "acquisition", connection.controller, connection.acquisition));
  daq::RigDevices d;
  // The receiver first, on an ephemeral port, so the served module knows where to send.
  std::unique_ptr<daq::CanTransport> transport = daq::OpenCanTransport("udp:127.0.0.1:0", /*listen=*/true);
  const std::string frames_to = transport->name();
  RigServerOptions served;
  served.speed = speed_;
  served.can = frames_to;
  auto owned = std::make_unique<RigServer>(truth_, served);
  RigServer& server = *owned;
  d.host = std::move(owned);
  d.acquisition = std::make_unique<daq::CanAcquisition>(std::move(transport), server.ReceiverOptions());
  daq::ModbusControllerOptions modbus;
  modbus.endpoint = server.modbus_endpoint();
  modbus.response_timeout = connection.response_timeout;
  d.controller = std::make_unique<daq::ModbusController>(modbus);
  d.description = fmt::format("{} [simulated in-process at {}x real time: {}]", truth_.rig, speed_, truth_.source);
  server.Start();
  spdlog::info("simulated rig: controller at {}, sensors to {}, {}x real time", modbus.endpoint.ToString(), frames_to,
               speed_);
  return d;
}

const RigServer* ServedRig(const daq::RigDevices& devices) {
  return dynamic_cast<const RigServer*>(devices.host.get());
}

}  // namespace strut::sim
