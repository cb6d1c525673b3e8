// A deterministic small plant for the rig runner's tests (tests/test_rig_run.cpp): a servo
// controller whose stroke follows its command (a sine about a static level, amplitude ramped in
// and out over whole cycles, static moves at the set-point's rate) and a damper whose force is a
// known function of stroke and velocity, sampled at a fixed rate on the monotonic clock. Behind
// the same interfaces as the rig: a daq::ControllerBackend (served over Modbus TCP by
// daq::ModbusControllerServer, or wrapped in-process by DirectController), a daq::AcquisitionModule
// (PlantAcquisition) and a CAN module streaming over UDP (PlantCanStreamer). Knobs inject faults.
// Header-only.
#pragma once

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <numbers>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "strut/daq/acquisition.h"
#include "strut/daq/can_acquisition.h"
#include "strut/daq/controller.h"
#include "strut/daq/device_error.h"

namespace strut::test {

struct PlantOptions {
  double sample_rate = 1000.0;  //!< Hz
  // force = stiffness (stroke - 0.1 m) + damping velocity + force_offset + force_drift t
  double stiffness = 2.0e5;   //!< N/m
  double damping = 4.0e3;     //!< N s/m
  double force_offset = 1.0e3;  //!< N
  double force_drift = 0.0;     //!< N/s: a response that never settles
  // pressure (gauge) = pressure0 + pressure_per_m stroke
  double pressure0 = 2.0e6, pressure_per_m = 1.0e7;
  //! stroke = static + tracking (command - static): < 1 makes the actuator fall short (under-peak).
  double tracking = 1.0;
  double stroke_offset = 0.0;  //!< m added to the stroke (following error, limit trips)
  double start_stroke = 0.1;   //!< m, where the actuator stands at the start
};

//! One sample of the plant.
struct PlantSample {
  std::uint64_t index = 0;
  std::int64_t t = 0;
  double stroke = 0.0, force = 0.0, pressure = 0.0, command = 0.0;
  daq::ControllerState state = daq::ControllerState::kDisarmed;
  double amplitude = 0.0;  //!< the command's present envelope
};

//! The servo loop and the damper. Thread-safe; time advances in sample steps to "now".
class Plant final : public daq::ControllerBackend {
 public:
  explicit Plant(PlantOptions o = {}) : o_(o), t0_(daq::MonotonicNs()), static_(o.start_stroke) {
    period_ns_ = 1e9 / o_.sample_rate;
    prev_stroke_ = o_.start_stroke;
  }

  std::optional<std::string> Apply(const daq::SetPoint& s) override {
    std::lock_guard lock(mutex_);
    AdvanceTo(daq::MonotonicNs());
    if (fault_word_ != 0) return "set-point refused: a fault is latched";
    if ((state_ == daq::ControllerState::kRunning || state_ == daq::ControllerState::kStopping) &&
        (s.static_position != sp_.static_position || s.frequency != sp_.frequency))
      return "set-point refused: static position or frequency changed while the sine runs";
    sp_ = s;
    has_sp_ = true;
    applied_.push_back(s);
    return std::nullopt;
  }

  std::optional<std::string> Execute(daq::ControllerCommand c) override {
    std::lock_guard lock(mutex_);
    AdvanceTo(daq::MonotonicNs());
    commands_.push_back(c);
    using S = daq::ControllerState;
    if (state_ == S::kFaulted && c != daq::ControllerCommand::kDisarm && c != daq::ControllerCommand::kResetFaults)
      return "refused: a fault is latched";
    switch (c) {
      case daq::ControllerCommand::kArm:
        if (!has_sp_) return "arm refused: no set-point";
        if (state_ != S::kDisarmed && state_ != S::kArmed) return "arm refused while running";
        state_ = S::kArmed;
        break;
      case daq::ControllerCommand::kRun:
        if (state_ != S::kArmed) return "run refused: not armed";
        if (std::abs(static_ - sp_.static_position) > 1e-12) return "run refused: not at the static level yet";
        state_ = S::kRunning;
        phase_ = 0.0;
        envelope_ = 0.0;
        cycles_ = 0;
        stop_pending_ = false;
        break;
      case daq::ControllerCommand::kStop:
        if (state_ == S::kRunning) stop_pending_ = true;
        break;
      case daq::ControllerCommand::kDisarm:
        state_ = S::kDisarmed;
        envelope_ = 0.0;
        break;
      case daq::ControllerCommand::kResetFaults:
        fault_word_ = 0;
        if (state_ == S::kFaulted) state_ = S::kDisarmed;
        break;
    }
    return std::nullopt;
  }

  daq::ControllerStatus Status() override {
    std::lock_guard lock(mutex_);
    AdvanceTo(daq::MonotonicNs());
    daq::ControllerStatus s;
    s.state = state_;
    s.mode = daq::ControlMode::kStroke;
    s.fault_word = fault_word_;
    using namespace daq::status_bits;
    if (state_ == daq::ControllerState::kArmed || state_ == daq::ControllerState::kRunning ||
        state_ == daq::ControllerState::kStopping)
      s.status_word |= kHydraulicsOn;
    if (state_ == daq::ControllerState::kArmed && std::abs(static_ - sp_.static_position) < 1e-12) s.status_word |= kAtStatic;
    if (state_ == daq::ControllerState::kRunning && !stop_pending_ && envelope_ >= sp_.amplitude) s.status_word |= kFullAmplitude;
    else if (state_ == daq::ControllerState::kRunning || state_ == daq::ControllerState::kStopping ||
             (state_ == daq::ControllerState::kArmed && std::abs(static_ - sp_.static_position) >= 1e-12))
      s.status_word |= kRamping;
    s.stroke = last_.stroke;
    s.force = last_.force;
    s.command = last_.command;
    s.cycles = static_cast<std::uint32_t>(cycles_);
    s.time_ms = static_cast<std::uint32_t>((last_.t - t0_) / 1'000'000);
    return s;
  }

  //! Samples taken since the last call (the acquisition's side).
  std::vector<PlantSample> TakeSamples() {
    std::lock_guard lock(mutex_);
    AdvanceTo(daq::MonotonicNs());
    std::vector<PlantSample> out(pending_.begin(), pending_.end());
    pending_.clear();
    return out;
  }
  //! Every sample so far (for checks against the truth).
  std::vector<PlantSample> history() const {
    std::lock_guard lock(mutex_);
    return history_;
  }
  std::vector<daq::SetPoint> applied() const {
    std::lock_guard lock(mutex_);
    return applied_;
  }
  std::vector<daq::ControllerCommand> commands() const {
    std::lock_guard lock(mutex_);
    return commands_;
  }
  void SetStrokeOffset(double m) {
    std::lock_guard lock(mutex_);
    o_.stroke_offset = m;
  }
  void SetTracking(double k) {
    std::lock_guard lock(mutex_);
    o_.tracking = k;
  }
  void InjectFault(std::uint16_t bits) {
    std::lock_guard lock(mutex_);
    fault_word_ |= bits;
    state_ = daq::ControllerState::kFaulted;
  }
  const PlantOptions& options() const { return o_; }
  double ForceOf(double stroke, double velocity, double t_s) const {
    return o_.stiffness * (stroke - 0.1) + o_.damping * velocity + o_.force_offset + o_.force_drift * t_s;
  }

 private:
  void AdvanceTo(std::int64_t now) {
    using S = daq::ControllerState;
    const double dt = 1.0 / o_.sample_rate;
    while (static_cast<double>(now - t0_) >= static_cast<double>(next_) * period_ns_) {
      const std::int64_t t = t0_ + static_cast<std::int64_t>(std::llround(static_cast<double>(next_) * period_ns_));
      if (state_ == S::kArmed) {
        const double step = sp_.static_rate * dt;
        const double d = sp_.static_position - static_;
        static_ = std::abs(d) <= step ? sp_.static_position : static_ + std::copysign(step, d);
      } else if (state_ == S::kRunning || state_ == S::kStopping) {
        const double per_cycle = sp_.ramp_cycles > 0 ? sp_.amplitude / sp_.ramp_cycles : sp_.amplitude;
        if (state_ == S::kRunning) envelope_ = std::min(sp_.amplitude, envelope_ + per_cycle * sp_.frequency * dt);
        if (state_ == S::kStopping) envelope_ = std::max(0.0, envelope_ - per_cycle * sp_.frequency * dt);
        phase_ += sp_.frequency * dt;
        if (phase_ >= 1.0 - 1e-9) {  // the end of a cycle: stops happen here
          phase_ -= 1.0;
          if (phase_ < 1e-9) phase_ = 0.0;
          ++cycles_;
          if (state_ == S::kRunning && stop_pending_) {
            state_ = sp_.ramp_cycles > 0 ? S::kStopping : S::kArmed;
            if (state_ == S::kArmed) envelope_ = 0.0;
          } else if (state_ == S::kStopping && envelope_ <= 1e-12 * std::max(sp_.amplitude, 1e-9)) {
            state_ = S::kArmed;
            envelope_ = 0.0;
            phase_ = 0.0;
          }
        }
      }
      const double command = static_ + envelope_ * std::sin(2.0 * std::numbers::pi * phase_);
      double stroke = (state_ == S::kDisarmed || state_ == S::kFaulted)
                          ? prev_stroke_
                          : static_ + o_.tracking * (command - static_) + o_.stroke_offset;
      const double velocity = next_ == 0 ? 0.0 : (stroke - prev_stroke_) / dt;
      PlantSample s;
      s.index = next_;
      s.t = t;
      s.stroke = stroke;
      s.force = ForceOf(stroke, velocity, static_cast<double>(next_) * dt);
      s.pressure = o_.pressure0 + o_.pressure_per_m * stroke;
      s.command = command;
      s.state = state_;
      s.amplitude = envelope_;
      if (state_ != S::kDisarmed && state_ != S::kFaulted &&
          (stroke < sp_.limits.stroke_min || stroke > sp_.limits.stroke_max)) {
        fault_word_ |= daq::fault_bits::kStrokeLimit;  // the controller's own interlock
        state_ = S::kFaulted;
      }
      prev_stroke_ = stroke;
      last_ = s;
      pending_.push_back(s);
      history_.push_back(s);
      ++next_;
    }
  }

  PlantOptions o_;
  mutable std::mutex mutex_;
  std::int64_t t0_;
  double period_ns_ = 1e6;
  std::uint64_t next_ = 0;
  daq::SetPoint sp_;
  bool has_sp_ = false;
  daq::ControllerState state_ = daq::ControllerState::kDisarmed;
  std::uint16_t fault_word_ = 0;
  double static_;
  double phase_ = 0.0, envelope_ = 0.0;
  long cycles_ = 0;
  bool stop_pending_ = false;
  double prev_stroke_ = 0.0;
  PlantSample last_;
  std::deque<PlantSample> pending_;
  std::vector<PlantSample> history_;
  std::vector<daq::SetPoint> applied_;
  std::vector<daq::ControllerCommand> commands_;
};

//! The plant's controller in-process (no Modbus): the same rules and errors as the real client.
//! Knobs: `fail` makes every call throw a connection error (a lost controller), `freeze_heartbeat`
//! stops the controller's heartbeat counter.
class DirectController final : public daq::ActuatorController {
 public:
  explicit DirectController(Plant& plant) : plant_(plant) {}
  std::uint16_t WriteSetPoint(const daq::SetPoint& s) override {
    Check("write set-point");
    std::string error;
    if (!s.IsValid(&error))
      throw daq::DeviceError(daq::DeviceError::Kind::kInvalidValue, Describe(), "write set-point", "set-point block", 0, error);
    if (auto reason = plant_.Apply(s))
      throw daq::DeviceError(daq::DeviceError::Kind::kRefused, Describe(), "write set-point", "sequence", 0, *reason);
    last_ = s;
    return ++sequence_;
  }
  daq::SetPoint ReadSetPoint() override {
    Check("read set-point");
    return last_;
  }
  void Command(daq::ControllerCommand c) override {
    Check("command");
    if (auto reason = plant_.Execute(c))
      throw daq::DeviceError(daq::DeviceError::Kind::kRefused, Describe(), "command", std::string(daq::ToString(c)), 0,
                             *reason);
  }
  daq::ControllerStatus ReadStatus() override {
    Check("read status");
    daq::ControllerStatus s = plant_.Status();
    if (!freeze_heartbeat) ++heartbeat_;
    s.heartbeat = heartbeat_;
    s.applied_sequence = sequence_;
    if (watchdog_ms_ > 0) s.status_word |= daq::status_bits::kWatchdogEnabled;
    return s;
  }
  void Heartbeat() override {
    Check("heartbeat");
    ++beats;
  }
  void SetWatchdog(std::chrono::milliseconds t) override {
    Check("set watchdog");
    watchdog_ms_ = static_cast<int>(t.count());
    watchdogs.push_back(watchdog_ms_);
  }
  std::string Describe() const override { return "direct://plant"; }

  std::atomic<bool> fail{false};
  std::atomic<bool> freeze_heartbeat{false};
  std::atomic<long> beats{0};
  std::vector<int> watchdogs;

 private:
  void Check(const char* what) const {
    if (fail.load())
      throw daq::DeviceError(daq::DeviceError::Kind::kConnection, Describe(), what, "", 104, "Connection reset by peer");
  }
  Plant& plant_;
  daq::SetPoint last_;
  std::uint16_t sequence_ = 0;
  std::uint16_t heartbeat_ = 0;
  int watchdog_ms_ = 0;
};

//! Calibrations of the plant's channels: 16-bit counts over each range (as sim's converters).
inline std::vector<daq::ChannelDescriptor> PlantChannels() {
  return {{"stroke", "m", daq::Calibration::FromRange16(-0.01, 0.3)},
          {"force", "N", daq::Calibration::FromRange16(-60e3, 60e3)},
          {"pressure", "Pa", daq::Calibration::FromRange16(-0.1e6, 20e6)}};
}

//! The plant's acquisition module in-process. Knobs: `freeze` (no more samples: a frozen
//! stream), `Gap(n)` (the next n samples are lost), `fail` (Read throws: the stream is lost).
class PlantAcquisition final : public daq::AcquisitionModule {
 public:
  explicit PlantAcquisition(Plant& plant, std::size_t block_sets = 20) : plant_(plant), block_sets_(block_sets) {
    description_.source = "plant acquisition";
    description_.sample_rate = plant.options().sample_rate;
    description_.channels = PlantChannels();
  }
  const daq::StreamDescription& description() const override { return description_; }
  void Start() override {
    plant_.TakeSamples();
    held_.clear();
    running_ = true;
    next_index_ = 0;
    last_sample_ns_ = daq::MonotonicNs();
  }
  void Stop() override { running_ = false; }
  daq::AcquiredBlock Read(std::chrono::nanoseconds timeout) override {
    if (!running_) throw daq::DeviceError(daq::DeviceError::Kind::kConnection, "plant", "read", "", 0, "not started");
    const std::int64_t deadline = daq::MonotonicNs() + timeout.count();
    for (;;) {
      if (fail.load()) throw daq::DeviceError(daq::DeviceError::Kind::kConnection, "plant acquisition", "receive", "", 5,
                                              "Input/output error");
      for (const PlantSample& s : plant_.TakeSamples()) held_.push_back(s);
      const std::int64_t due = daq::MonotonicNs() - delay_ns.load();
      for (; !held_.empty() && held_.front().t <= due; held_.pop_front()) {
        const PlantSample& s = held_.front();
        if (freeze.load()) continue;
        if (skip_ > 0) {
          --skip_;
          ++lost_;
          continue;
        }
        queue_.push_back({s, std::exchange(lost_, 0)});
      }
      if (queue_.size() >= block_sets_ || daq::MonotonicNs() >= deadline) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    daq::AcquiredBlock b;
    const std::int64_t now = daq::MonotonicNs();
    if (queue_.empty()) {
      if (now - last_sample_ns_ > 250'000'000) {
        b.quality.flags |= daq::Quality::kStale;
        if (!stale_noted_) {
          b.events.push_back({daq::AcquisitionEvent::Kind::kStale, now, next_index_, 0, "no sample for 250 ms: frozen"});
          stale_noted_ = true;
        }
      }
      return b;
    }
    stale_noted_ = false;
    // A block never spans a gap: it ends before the next sample that follows lost ones.
    std::size_t n = 1;
    while (n < std::min(queue_.size(), block_sets_) && queue_[n].second == 0) ++n;
    const std::uint64_t lost = queue_.front().second;
    b.first_index = next_index_ + lost;
    if (lost > 0) {
      b.lost_before = lost;
      b.quality.flags |= daq::Quality::kSequenceGap;
      b.events.push_back({daq::AcquisitionEvent::Kind::kSequenceGap, now, b.first_index, lost,
                          std::to_string(lost) + " sample sets lost"});
      next_index_ += lost;
    }
    b.values.assign(3, {});
    b.counts.assign(3, {});
    for (std::size_t i = 0; i < n; ++i) {
      const PlantSample& s = queue_.front().first;
      b.time_ns.push_back(s.t);
      const double v[3] = {s.stroke, s.force, s.pressure};
      for (int k = 0; k < 3; ++k) {
        const daq::Calibration& c = description_.channels[k].calibration;
        const std::int16_t counts = c.ToCounts16(v[k]);
        b.counts[k].push_back(counts);
        b.values[k].push_back(c.ToSi(counts));
      }
      queue_.pop_front();
    }
    next_index_ += n;
    last_sample_ns_ = b.time_ns.back();
    b.last_frame_ns = now;
    b.clock = daq::NowTimePair();
    return b;
  }
  const daq::AcquisitionStats& stats() const override { return stats_; }

  //! The next n samples are lost (a sequence gap).
  void Gap(std::uint64_t n) { skip_ += n; }
  std::atomic<bool> freeze{false};
  std::atomic<bool> fail{false};
  //! Each sample arrives this long after its time stamp: a stream late behind the controller.
  std::atomic<std::int64_t> delay_ns{0};

 private:
  Plant& plant_;
  std::size_t block_sets_;
  daq::StreamDescription description_;
  daq::AcquisitionStats stats_;
  bool running_ = false;
  std::deque<PlantSample> held_;  //!< taken from the plant, not yet arrived (delay_ns)
  std::deque<std::pair<PlantSample, std::uint64_t>> queue_;  //!< samples and the sets lost just before each
  std::uint64_t next_index_ = 0;
  std::atomic<std::uint64_t> skip_{0};
  std::uint64_t lost_ = 0;
  std::int64_t last_sample_ns_ = 0;
  bool stale_noted_ = false;
};

//! The plant's acquisition as a CAN module on a transport (UDP for a runner in another process):
//! every few ms the samples due are sent, a status frame every 20 sets. By default classic frames
//! of 3 channels (PlantChannels); another `layout` and `channels` (in frame order, each encoded
//! with its calibration; a channel other than stroke, force and pressure reads 1234 counts) make
//! a module of another make.
class PlantCanStreamer {
 public:
  PlantCanStreamer(Plant& plant, std::unique_ptr<daq::CanTransport> transport, daq::CanFrameLayout layout = Layout(),
                   std::vector<daq::ChannelDescriptor> channels = PlantChannels())
      : plant_(plant), sender_(std::move(transport), layout, 20), channels_(std::move(channels)) {
    sender_.flush_sets = 8;
    thread_ = std::thread([this] { Loop(); });
  }
  ~PlantCanStreamer() {
    stop_ = true;
    thread_.join();
  }
  static daq::CanFrameLayout Layout() {
    daq::CanFrameLayout l;
    l.channels = 3;
    l.module = 1;
    return l;
  }

 private:
  void Loop() {
    std::vector<std::int16_t> set(channels_.size());
    while (!stop_) {
      try {
        for (const PlantSample& s : plant_.TakeSamples()) {
          for (std::size_t k = 0; k < channels_.size(); ++k) {
            const daq::ChannelDescriptor& c = channels_[k];
            set[k] = c.name == "stroke"     ? c.calibration.ToCounts16(s.stroke)
                     : c.name == "force"    ? c.calibration.ToCounts16(s.force)
                     : c.name == "pressure" ? c.calibration.ToCounts16(s.pressure)
                                            : std::int16_t{1234};
          }
          sender_.Add(set);
        }
        sender_.Flush();
      } catch (const std::exception&) {
        // The receiver is gone for a moment (a killed runner): the module streams on regardless.
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(3));
    }
  }
  Plant& plant_;
  daq::CanAcquisitionSender sender_;
  std::vector<daq::ChannelDescriptor> channels_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace strut::test
