// The channel file (docs/rig-run.md "The channel file"): how a real acquisition module streams the
// channels a run records: the module, the frame kind, and per channel (stroke, force, pressure)
// its place in the sample set and its calibration. Without one, `strut rig run` expects the
// simulated rig's module (sim::CanChannels: module 1, classic frames, stroke force pressure).
#pragma once

#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "strut/daq/can_acquisition.h"

namespace strut::rig {

//! A channel file refused: what() names the file, the line and the key.
class ChannelFileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

//! What a channel file says: the receiving side's layout and channels.
struct ChannelMap {
  daq::CanFrameLayout layout;
  //! One per reading of a sample set, in frame order: the named channels with their calibration
  //! to SI (m, N, Pa); a reading the file does not name is kept as "channel<N>" in counts.
  std::vector<daq::ChannelDescriptor> channels;
  std::string pressure_reference = "gauge";  //!< "gauge" or "absolute"
};

//! Parses a channel file (TOML):
//!
//!     module = 7            # 0..63
//!     frame = "fd"          # "classic" (one sample set per frame) or "fd" (CAN FD)
//!     channels = 4          # readings per sample set (default: the highest index + 1)
//!     [stroke]              # also [force] (both required) and [pressure]
//!     index = 3             # 0-based place in the sample set
//!     unit = "mm"           # stroke m | mm; force N | kN; pressure Pa | kPa | bar | MPa
//!     gain = 0.01           # unit per count
//!     offset = 150.0        # unit at zero counts (default 0)
//!     range_min = -10.0     # optional pair: the calibrated range, readings outside it flagged
//!     range_max = 310.0
//!     # [pressure] only: reference = "gauge" | "absolute" (default gauge)
//!
//! Throws ChannelFileError naming `source`, the line and the key.
ChannelMap ParseChannelFile(std::string_view text, const std::string& source);
ChannelMap ReadChannelFile(const std::string& path);

}  // namespace strut::rig
