// The matrix runner's steady-state detector (steady_state.h) re-run on a replayed stream
// (docs/replay.md "Steady-state detection on replay"): each periodic experiment's blocks cut into
// whole cycles and judged as the runner judges them live. `strut replay` prints its verdicts;
// the live monitor of a replay shows its figures while the experiment plays.
#pragma once

#include <optional>
#include <vector>

#include "strut/daq/replay.h"
#include "strut/rig/steady_state.h"

namespace strut::rig {

class SteadyStateOnReplay : public daq::ReplayObserver {
 public:
  struct Row {
    bool judged = false;  //!< periodic with whole samples per cycle, stroke and force there
    SteadyStateVerdict verdict;
  };

  void BeginExperiment(const daq::ReplayedExperiment& x) override;
  void Block(const daq::ReplayedExperiment& x, const daq::AcquiredBlock& b) override;
  void EndExperiment(const daq::ReplayedExperiment& x) override;

  //! One row per experiment begun so far, in replay order.
  const std::vector<Row>& rows() const { return rows_; }
  //! The verdict so far of the experiment playing now; nullptr when it is not judged.
  const SteadyStateVerdict* live() const { return detector_ ? &detector_->verdict() : nullptr; }
  //! Whole cycles of the experiment playing now (0 when it is not judged).
  long cycles() const { return summariser_ ? summariser_->cycles() : 0; }

 private:
  std::vector<Row> rows_;
  std::optional<CycleSummariser> summariser_;
  std::optional<SteadyStateDetector> detector_;
  int stroke_ = -1, force_ = -1, pressure_ = -1;
};

}  // namespace strut::rig
