#include "strut/rig/replay_steady_state.h"

#include <span>
#include <string>

namespace strut::rig {

void SteadyStateOnReplay::BeginExperiment(const daq::ReplayedExperiment& x) {
  rows_.emplace_back();
  summariser_.reset();
  detector_.reset();
  const auto per_cycle = daq::WholeSamplesPerPeriod(x.stream.sample_rate, x.header.frequency, 2);
  if (x.header.kind != daq::ExperimentKind::kPeriodic || !per_cycle) return;
  stroke_ = force_ = pressure_ = -1;
  for (std::size_t c = 0; c < x.stream.channels.size(); ++c) {
    const std::string& name = x.stream.channels[c].name;
    if (name == "stroke") stroke_ = static_cast<int>(c);
    if (name == "force") force_ = static_cast<int>(c);
    if (name == "pressure") pressure_ = static_cast<int>(c);
  }
  if (stroke_ < 0 || force_ < 0) return;
  summariser_.emplace(*per_cycle);
  detector_.emplace();
  rows_.back().judged = true;
}

void SteadyStateOnReplay::Block(const daq::ReplayedExperiment&, const daq::AcquiredBlock& b) {
  if (!summariser_) return;
  if (b.quality.has(daq::Quality::kSequenceGap)) summariser_->Restart();
  const std::span<const double> pressure =
      pressure_ >= 0 ? std::span<const double>(b.values[pressure_]) : std::span<const double>();
  for (const CycleSummary& c : summariser_->Add(b.time_ns, b.values[stroke_], b.values[force_], pressure))
    detector_->Add(c);
}

void SteadyStateOnReplay::EndExperiment(const daq::ReplayedExperiment&) {
  if (detector_) rows_.back().verdict = detector_->verdict();
}

}  // namespace strut::rig
