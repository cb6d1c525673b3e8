// Names of the controller's enumerations and the set-point checks. Standard library only (the
// libFuzzer target builds this file with clang alone).
#include <cmath>
#include <cstdio>
#include <string>

#include "set_point_check.h"
#include "strut/daq/controller.h"

namespace strut::daq {

std::string_view ToString(ControlMode mode) {
  switch (mode) {
    case ControlMode::kStroke: return "stroke";
    case ControlMode::kForce: return "force";
  }
  return "unknown mode";
}

std::string_view ToString(ControllerCommand command) {
  switch (command) {
    case ControllerCommand::kArm: return "arm";
    case ControllerCommand::kRun: return "run";
    case ControllerCommand::kStop: return "stop";
    case ControllerCommand::kDisarm: return "disarm";
    case ControllerCommand::kResetFaults: return "reset-faults";
  }
  return "unknown command";
}

std::string_view ToString(ControllerState state) {
  switch (state) {
    case ControllerState::kDisarmed: return "disarmed";
    case ControllerState::kArmed: return "armed";
    case ControllerState::kRunning: return "running";
    case ControllerState::kStopping: return "stopping";
    case ControllerState::kFaulted: return "faulted";
  }
  return "unknown state";
}

std::optional<ControlMode> ControlModeFrom(std::uint16_t value) {
  if (value == 1) return ControlMode::kStroke;
  if (value == 2) return ControlMode::kForce;
  return std::nullopt;
}

std::optional<ControllerCommand> ControllerCommandFrom(std::uint16_t value) {
  if (value >= 1 && value <= 5) return static_cast<ControllerCommand>(value);
  return std::nullopt;
}

std::optional<ControllerState> ControllerStateFrom(std::uint16_t value) {
  if (value <= 4) return static_cast<ControllerState>(value);
  return std::nullopt;
}

namespace {

std::string BitsText(std::uint16_t word, const char* const (&names)[16]) {
  if (word == 0) return "none";
  std::string text;
  for (int bit = 0; bit < 16; ++bit) {
    if (!(word & (1u << bit))) continue;
    if (!text.empty()) text += ' ';
    text += names[bit] ? std::string(names[bit]) : "bit" + std::to_string(bit);
  }
  return text;
}

}  // namespace

std::string StatusBitsText(std::uint16_t status_word) {
  static const char* const kNames[16] = {"hydraulics-on", "at-static", "ramping", "full-amplitude",
                                         "watchdog-enabled", "limit-indicated"};
  return BitsText(status_word, kNames);
}

std::string FaultBitsText(std::uint16_t fault_word) {
  static const char* const kNames[16] = {"stroke-limit", "force-limit",    "following-error", "heartbeat-lost",
                                         "hydraulics",   "emergency-stop", "device"};
  return BitsText(fault_word, kNames);
}

namespace detail {

std::string Number(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.6g", value);
  return text;
}

namespace {

std::optional<SetPointProblem> Problem(std::string_view field, std::string message, bool not_finite = false) {
  return SetPointProblem{field, std::string(field) + " " + std::move(message), not_finite};
}

}  // namespace

std::optional<SetPointProblem> CheckSetPoint(const SetPoint& s) {
  if (!ControlModeFrom(static_cast<std::uint16_t>(s.mode)))
    return Problem("mode", Number(static_cast<double>(s.mode)) + " is neither stroke (1) nor force (2) control");
  const bool stroke_mode = s.mode == ControlMode::kStroke;
  const char* unit = stroke_mode ? "m" : "N";
  const struct {
    std::string_view field;
    double value;
  } values[] = {{"static_position", s.static_position}, {"amplitude", s.amplitude},
                {"frequency", s.frequency},             {"static_rate", s.static_rate},
                {"stroke_min", s.limits.stroke_min},    {"stroke_max", s.limits.stroke_max},
                {"force_min", s.limits.force_min},      {"force_max", s.limits.force_max}};
  for (const auto& v : values)
    if (!std::isfinite(v.value)) return Problem(v.field, "is " + Number(v.value) + ", not a finite number", true);
  if (s.ramp_cycles < 0 || s.ramp_cycles > SetPoint::kMaxRampCycles)
    return Problem("ramp_cycles", Number(s.ramp_cycles) + " is outside 0.." + Number(SetPoint::kMaxRampCycles));
  if (s.frequency < 0.0 || s.frequency > SetPoint::kMaxFrequency)
    return Problem("frequency", Number(s.frequency) + " Hz is outside 0.." + Number(SetPoint::kMaxFrequency) + " Hz");
  if (s.amplitude < 0.0) return Problem("amplitude", Number(s.amplitude) + " " + unit + " is negative");
  if (s.amplitude > 0.0 && s.frequency == 0.0)
    return Problem("frequency", "is 0 Hz with a non-zero amplitude");
  if (!(s.static_rate > 0.0)) return Problem("static_rate", Number(s.static_rate) + " is not positive");
  const ControllerLimits& l = s.limits;
  if (std::abs(l.stroke_min) > SetPoint::kMaxAbsStroke)
    return Problem("stroke_min", Number(l.stroke_min) + " m is beyond +-" + Number(SetPoint::kMaxAbsStroke) + " m");
  if (std::abs(l.stroke_max) > SetPoint::kMaxAbsStroke)
    return Problem("stroke_max", Number(l.stroke_max) + " m is beyond +-" + Number(SetPoint::kMaxAbsStroke) + " m");
  if (std::abs(l.force_min) > SetPoint::kMaxAbsForce)
    return Problem("force_min", Number(l.force_min) + " N is beyond +-" + Number(SetPoint::kMaxAbsForce) + " N");
  if (std::abs(l.force_max) > SetPoint::kMaxAbsForce)
    return Problem("force_max", Number(l.force_max) + " N is beyond +-" + Number(SetPoint::kMaxAbsForce) + " N");
  if (!(l.stroke_min < l.stroke_max))
    return Problem("stroke_max", Number(l.stroke_max) + " m is not above stroke_min " + Number(l.stroke_min) + " m");
  if (!(l.force_min < l.force_max))
    return Problem("force_max", Number(l.force_max) + " N is not above force_min " + Number(l.force_min) + " N");
  const double low = stroke_mode ? l.stroke_min : l.force_min;
  const double high = stroke_mode ? l.stroke_max : l.force_max;
  const std::string range = Number(low) + " .. " + Number(high) + " " + unit;
  if (s.static_position < low || s.static_position > high)
    return Problem("static_position", Number(s.static_position) + " " + unit + " is outside the " +
                                          (stroke_mode ? "stroke" : "force") + " limits " + range);
  if (s.static_position - s.amplitude < low || s.static_position + s.amplitude > high)
    return Problem("amplitude", Number(s.amplitude) + " " + unit + " about the static level " +
                                    Number(s.static_position) + " " + unit + " leaves the " +
                                    (stroke_mode ? "stroke" : "force") + " limits " + range);
  return std::nullopt;
}

}  // namespace detail

bool SetPoint::IsValid(std::string* error) const {
  const auto problem = detail::CheckSetPoint(*this);
  if (problem && error) *error = problem->message;
  return !problem;
}

}  // namespace strut::daq
