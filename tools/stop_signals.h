// SIGINT and SIGTERM for a command that runs until told to stop (`strut rig run`, `strut rig
// serve-sim`).
#pragma once

#include <signal.h>

namespace strut::tools {

//! SIGINT and SIGTERM go to `handler` while this lives (a run, a served rig); the handlers they
//! had are restored after, also when what runs throws.
class StopSignals {
 public:
  explicit StopSignals(void (*handler)(int));
  ~StopSignals();
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;

 private:
  struct sigaction old_int_ {}, old_term_ {};
};

}  // namespace strut::tools
