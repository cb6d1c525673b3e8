// The actuator controller of the shaker rig as the rest of strut sees it: one small interface
// (ActuatorController) that a driver implements for real hardware (ModbusController) and that
// tests and the simulated rig stand behind (ControllerBackend served by ModbusControllerServer).
// docs/register-map.md describes the protocol, the threading and timeout rules and how faults
// appear.
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace strut::daq {

//! What the servo loop closes on. The set-point's static level and amplitude are in the units of
//! the controlled quantity: metres in stroke control, newtons in force control.
enum class ControlMode : std::uint16_t { kStroke = 1, kForce = 2 };

//! Commands to the controller (MTS practice: arm holds the static level with hydraulics on, run
//! starts the sine with an amplitude ramp in whole cycles, stop ramps out at the end of a cycle
//! and holds the static level again, disarm switches hydraulics off).
enum class ControllerCommand : std::uint16_t { kArm = 1, kRun = 2, kStop = 3, kDisarm = 4, kResetFaults = 5 };

enum class ControllerState : std::uint16_t {
  kDisarmed = 0,  //!< hydraulics off
  kArmed = 1,     //!< holding (or moving at the static rate to) the static level
  kRunning = 2,   //!< sine about the static level, amplitude ramps included
  kStopping = 3,  //!< ramping out; becomes kArmed at the static level
  kFaulted = 4,   //!< a fault latched; needs kResetFaults, then kArm
};

std::string_view ToString(ControlMode mode);
std::string_view ToString(ControllerCommand command);
std::string_view ToString(ControllerState state);
//! The mode, command or state of a register value; nullopt for a value that names none.
std::optional<ControlMode> ControlModeFrom(std::uint16_t value);
std::optional<ControllerCommand> ControllerCommandFrom(std::uint16_t value);
std::optional<ControllerState> ControllerStateFrom(std::uint16_t value);

//! Bits of ControllerStatus::status_word.
namespace status_bits {
inline constexpr std::uint16_t kHydraulicsOn = 1u << 0;
inline constexpr std::uint16_t kAtStatic = 1u << 1;         //!< at the static level, no sine
inline constexpr std::uint16_t kRamping = 1u << 2;          //!< amplitude or static level ramping
inline constexpr std::uint16_t kFullAmplitude = 1u << 3;    //!< sine at the set amplitude
inline constexpr std::uint16_t kWatchdogEnabled = 1u << 4;  //!< the client heartbeat is watched
inline constexpr std::uint16_t kLimitIndicated = 1u << 5;   //!< a limit detector with action "indicate" fired
}  // namespace status_bits

//! Bits of ControllerStatus::fault_word. Faults latch until kResetFaults.
namespace fault_bits {
inline constexpr std::uint16_t kStrokeLimit = 1u << 0;
inline constexpr std::uint16_t kForceLimit = 1u << 1;
inline constexpr std::uint16_t kFollowingError = 1u << 2;  //!< command minus feedback too large
inline constexpr std::uint16_t kHeartbeatLost = 1u << 3;   //!< the client's heartbeat stopped (watchdog)
inline constexpr std::uint16_t kHydraulics = 1u << 4;      //!< supply pressure lost
inline constexpr std::uint16_t kEmergencyStop = 1u << 5;
inline constexpr std::uint16_t kDevice = 1u << 6;  //!< the controller's own failure (backend error)
}  // namespace fault_bits

//! The names of the bits set, e.g. "hydraulics-on at-static"; "none" for 0. Unknown bits as "bit12".
std::string StatusBitsText(std::uint16_t status_word);
std::string FaultBitsText(std::uint16_t fault_word);

//! Limits the controller enforces with an interlock (hydraulics off, fault latched).
struct ControllerLimits {
  double stroke_min = -0.01;  //!< m
  double stroke_max = 0.36;   //!< m
  double force_min = -5.0e4;  //!< N
  double force_max = 5.0e4;   //!< N
  friend bool operator==(const ControllerLimits&, const ControllerLimits&) = default;
};

//! The set-point block: written as a whole and applied as a whole, or not at all.
struct SetPoint {
  ControlMode mode = ControlMode::kStroke;
  double static_position = 0.0;  //!< mean of the command: m (stroke control) or N (force control)
  double amplitude = 0.0;        //!< m or N, >= 0; 0 holds the static level
  double frequency = 0.0;        //!< Hz, 0 <= f <= kMaxFrequency; > 0 when amplitude > 0
  int ramp_cycles = 2;           //!< whole cycles of amplitude ramp in and out, 0..kMaxRampCycles
  double static_rate = 0.01;     //!< m/s or N/s, > 0: rate limit of moves to the static level
  ControllerLimits limits;

  static constexpr double kMaxFrequency = 200.0;        //!< Hz
  static constexpr int kMaxRampCycles = 1000;
  static constexpr double kMaxAbsStroke = 10.0;         //!< m, any stroke value or limit
  static constexpr double kMaxAbsForce = 1.0e7;         //!< N, any force value or limit

  //! True when every value is finite and in range, the limits are ordered and the whole sine
  //! (static +- amplitude) lies within the limits of the controlled quantity. Otherwise false,
  //! with `error` (if given) naming the field and the range.
  bool IsValid(std::string* error = nullptr) const;
  friend bool operator==(const SetPoint&, const SetPoint&) = default;
};

//! A snapshot of the controller.
struct ControllerStatus {
  ControllerState state = ControllerState::kDisarmed;
  ControlMode mode = ControlMode::kStroke;
  std::uint16_t status_word = 0;       //!< status_bits
  std::uint16_t fault_word = 0;        //!< fault_bits, latched
  std::uint16_t applied_sequence = 0;  //!< sequence number of the set-point in force (0: none yet)
  std::uint16_t heartbeat = 0;         //!< counts up while the controller runs (wraps at 65536)
  double stroke = 0.0;                 //!< actual stroke, m
  double force = 0.0;                  //!< actual force, N
  double command = 0.0;                //!< present command of the servo loop, m or N (as the mode)
  std::uint32_t cycles = 0;            //!< whole sine cycles completed since the last run command
  std::uint32_t time_ms = 0;           //!< controller clock, ms (wraps after 49 days)

  bool faulted() const { return fault_word != 0 || state == ControllerState::kFaulted; }
  friend bool operator==(const ControllerStatus&, const ControllerStatus&) = default;
};

//! The actuator controller as a client (the rig runner) uses it. Every call either completes
//! within the implementation's stated timeouts or throws daq::DeviceError; none blocks forever.
//! Implementations document which threads may call them (ModbusController: any).
class ActuatorController {
 public:
  virtual ~ActuatorController() = default;

  //! Sends the whole set-point block; the controller applies all of it or none of it. Returns the
  //! sequence number under which it was applied (ControllerStatus::applied_sequence shows it).
  //! Throws DeviceError kInvalidValue (not sent) when !set_point.IsValid(), kRefused when the
  //! controller refuses it (e.g. a mode change while running).
  virtual std::uint16_t WriteSetPoint(const SetPoint& set_point) = 0;
  //! The set-point block as the controller holds it (the last one written, applied or not).
  virtual SetPoint ReadSetPoint() = 0;
  //! Throws DeviceError kRefused when the controller's state does not allow the command.
  virtual void Command(ControllerCommand command) = 0;
  virtual ControllerStatus ReadStatus() = 0;
  //! One beat of the client's heartbeat. With a watchdog set, the controller stops and latches
  //! fault_bits::kHeartbeatLost when no beat arrives within the watchdog time: call it from the
  //! loop whose liveness it proves (the runner), not from a timer thread.
  virtual void Heartbeat() = 0;
  //! Watchdog time of the client heartbeat; zero switches the watchdog off. At most 65535 ms.
  virtual void SetWatchdog(std::chrono::milliseconds timeout) = 0;
  //! The device for messages, e.g. "modbus-tcp://127.0.0.1:1502".
  virtual std::string Describe() const = 0;

  void Arm() { Command(ControllerCommand::kArm); }
  void Run() { Command(ControllerCommand::kRun); }
  void Stop() { Command(ControllerCommand::kStop); }
  void Disarm() { Command(ControllerCommand::kDisarm); }
  void ResetFaults() { Command(ControllerCommand::kResetFaults); }
};

//! The device side of the controller: what a server (ModbusControllerServer) serves. The real
//! servo loop, the simulated rig or a fake. The server calls it from its one thread only.
class ControllerBackend {
 public:
  virtual ~ControllerBackend() = default;
  //! A complete, valid (SetPoint::IsValid) set-point committed by a client. Returns a reason when
  //! refused (the state does not allow it); nothing is applied then.
  virtual std::optional<std::string> Apply(const SetPoint& set_point) = 0;
  //! Returns a reason when the command is refused in the present state.
  virtual std::optional<std::string> Execute(ControllerCommand command) = 0;
  //! The present status. The server fills applied_sequence and heartbeat itself and adds its own
  //! fault bits (kHeartbeatLost).
  virtual ControllerStatus Status() = 0;
};

}  // namespace strut::daq
