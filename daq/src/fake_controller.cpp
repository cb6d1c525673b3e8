#include "strut/daq/fake_controller.h"

#include <stdexcept>

namespace strut::daq {

std::optional<std::string> FakeControllerBackend::Apply(const SetPoint& set_point) {
  std::lock_guard lock(mutex_);
  const bool moving = status_.state == ControllerState::kRunning || status_.state == ControllerState::kStopping;
  if (moving && has_set_point_ && set_point.mode != status_.mode)
    return "cannot change from " + std::string(ToString(status_.mode)) + " to " +
           std::string(ToString(set_point.mode)) + " control while " + std::string(ToString(status_.state));
  applied_.push_back(set_point);
  has_set_point_ = true;
  status_.mode = set_point.mode;
  if (status_.state == ControllerState::kArmed) status_.command = set_point.static_position;
  return std::nullopt;
}

std::optional<std::string> FakeControllerBackend::Execute(ControllerCommand command) {
  std::lock_guard lock(mutex_);
  const ControllerState state = status_.state;
  const std::string in = " while " + std::string(ToString(state));
  if (state == ControllerState::kFaulted && command != ControllerCommand::kDisarm &&
      command != ControllerCommand::kResetFaults)
    return std::string(ToString(command)) + " refused: a fault is latched (reset faults first)";
  switch (command) {
    case ControllerCommand::kArm:
      if (!has_set_point_) return "arm refused: no set-point applied yet";
      if (state != ControllerState::kDisarmed && state != ControllerState::kArmed) return "arm refused" + in;
      status_.state = ControllerState::kArmed;
      status_.status_word = status_bits::kHydraulicsOn | status_bits::kAtStatic;
      status_.command = applied_.back().static_position;
      break;
    case ControllerCommand::kRun:
      if (state != ControllerState::kArmed) return "run refused: the controller is not armed (it is " +
                                                   std::string(ToString(state)) + ")";
      status_.state = ControllerState::kRunning;
      status_.status_word = status_bits::kHydraulicsOn | status_bits::kFullAmplitude;
      status_.cycles = 0;
      break;
    case ControllerCommand::kStop:
      if (state != ControllerState::kRunning && state != ControllerState::kStopping && state != ControllerState::kArmed)
        return "stop refused" + in;
      if (state != ControllerState::kArmed) {
        status_.state = ControllerState::kArmed;
        status_.status_word = status_bits::kHydraulicsOn | status_bits::kAtStatic;
      }
      break;
    case ControllerCommand::kDisarm:
      status_.state = ControllerState::kDisarmed;
      status_.status_word = 0;
      break;
    case ControllerCommand::kResetFaults:
      status_.fault_word = 0;
      if (state == ControllerState::kFaulted) status_.state = ControllerState::kDisarmed;
      break;
  }
  commands_.push_back(command);
  return std::nullopt;
}

ControllerStatus FakeControllerBackend::Status() {
  std::lock_guard lock(mutex_);
  if (fail_status_) throw std::runtime_error("fake backend: status unavailable (injected failure)");
  return status_;
}

std::vector<SetPoint> FakeControllerBackend::applied() const {
  std::lock_guard lock(mutex_);
  return applied_;
}

std::vector<ControllerCommand> FakeControllerBackend::commands() const {
  std::lock_guard lock(mutex_);
  return commands_;
}

void FakeControllerBackend::InjectFault(std::uint16_t fault_bits) {
  std::lock_guard lock(mutex_);
  status_.fault_word |= fault_bits;
  status_.state = ControllerState::kFaulted;
  status_.status_word = 0;
}

void FakeControllerBackend::SetStatus(const ControllerStatus& status, bool replace_all) {
  std::lock_guard lock(mutex_);
  if (replace_all) {
    status_ = status;
  } else {
    const ControllerState state = status_.state;
    const ControlMode mode = status_.mode;
    const std::uint16_t faults = status_.fault_word;
    status_ = status;
    status_.state = state;
    status_.mode = mode;
    status_.fault_word = faults;
  }
}

void FakeControllerBackend::FailStatus(bool fail) {
  std::lock_guard lock(mutex_);
  fail_status_ = fail;
}

}  // namespace strut::daq
