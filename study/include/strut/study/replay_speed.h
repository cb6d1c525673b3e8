// How fast a recorded session replays as fast as possible (`strut bench replay`, docs/replay.md
// "Figures"): in sample sets per CPU second, the replay alone, replay into the recorder (what
// `strut replay -o` does) and replay sent as CAN frames over UDP on loopback (`strut replay --to`).
#pragma once

#include <string>
#include <vector>

#include "strut/daq/session.h"

namespace strut::study {

//! One periodic experiment of `seconds` (whole 1 Hz periods) at `rate` as strut's recorder stores
//! a CAN stream: stroke, force and pressure with their counts and calibration, sequence and status.
daq::Session ReplayBenchSession(double seconds, double rate);

struct ReplayFigure {
  std::string name;
  double wall = 0.0, cpu = 0.0;  //!< s
};

//! The three replays of `session`; the recording goes to `recording_path` and is removed.
std::vector<ReplayFigure> MeasureReplay(const daq::Session& session, const std::string& recording_path);

}  // namespace strut::study
