// An in-memory controller backend for tests: the state machine of a servo controller without a
// servo loop. It records what it was told and returns the status a test sets.
#pragma once

#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "strut/daq/controller.h"

namespace strut::daq {

//! Thread-safe: a test may inspect or change it while a server calls it.
//! Rules (those of a servo controller, simplified): a set-point is refused while running or
//! stopping when it changes the mode; arm needs a set-point and no fault; run needs armed;
//! stop is accepted when running (and, doing nothing, when armed); disarm always; a latched
//! fault refuses everything but disarm and reset-faults.
class FakeControllerBackend final : public ControllerBackend {
 public:
  std::optional<std::string> Apply(const SetPoint& set_point) override;
  std::optional<std::string> Execute(ControllerCommand command) override;
  ControllerStatus Status() override;

  //! The set-points applied and the commands executed, oldest first.
  std::vector<SetPoint> applied() const;
  std::vector<ControllerCommand> commands() const;
  //! Latches fault bits (state kFaulted), as a limit detector of the controller would.
  void InjectFault(std::uint16_t fault_bits);
  //! Sets the actual values and counters the status reports (state, mode and fault word stay the
  //! state machine's unless `replace_all`, which returns `status` as it is until the next call).
  void SetStatus(const ControllerStatus& status, bool replace_all = false);
  //! Makes Status() throw (a backend that fails), to test the server's handling.
  void FailStatus(bool fail);

 private:
  mutable std::mutex mutex_;
  std::vector<SetPoint> applied_;
  std::vector<ControllerCommand> commands_;
  ControllerStatus status_;
  bool has_set_point_ = false;
  bool fail_status_ = false;
};

}  // namespace strut::daq
