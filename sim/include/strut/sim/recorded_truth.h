// The truth a simulated session was produced from, recorded in the session itself (a `/truth`
// group, docs/simulated-rig.md "Recorded truth"), so that tests and studies compare estimates
// with the values the rig simulated, read back from the file.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "strut/daq/session.h"
#include "strut/ident/parameters.h"
#include "strut/sim/truth.h"

namespace strut::sim {

//! Name of the session's extra root group that holds the truth.
inline constexpr std::string_view kTruthGroup = "truth";

//! The truth as a session records it.
struct RecordedTruth {
  std::string composition;          //!< the simulated model, e.g. "2dof+viscous-damping"
  std::string source;               //!< where the truth came from (file, built-in, drawn)
  std::optional<DrawRecord> drawn;  //!< set for a drawn unit
  //! The model's parameters (stroke input) holding exactly the recorded values.
  ident::ParameterSet parameters;
};

//! Adds (or replaces) the `/truth` group of `session`: composition, source, the draw (seed, base,
//! effects and their sizes) when drawn, and every parameter of `parameters` by key with its name,
//! unit and value (float64).
void RecordTruth(const Truth& truth, const ident::ParameterSet& parameters, const std::string& composition,
                 daq::Session& session);
//! The same with the truth's own model (stroke input) and parameter values, as a simulated rig
//! records them.
void RecordTruth(const Truth& truth, daq::Session& session);
//! The `/truth` group RecordTruth adds, as a recording's metadata groups
//! (daq::RecordingMetadata::groups) for a session recorded from the rig that runs `truth`.
std::vector<daq::MetadataGroup> TruthMetadata(const Truth& truth);

//! The truth recorded in a session; nullopt when it has no `/truth` group (a measured session, or
//! one written before strut recorded truths). Throws TruthError naming the session file and the
//! item when the group is malformed (missing attribute, unknown composition, a parameter the model
//! lacks or one of the model's parameters missing).
std::optional<RecordedTruth> ReadRecordedTruth(const daq::Session& session);

}  // namespace strut::sim
