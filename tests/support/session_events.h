// The events of a recorded session, for the tests of the recorder, the replay and the rig runner
// (on strut_daq, which those tests link).
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "strut/daq/session.h"

namespace strut::test {

//! The events a recorded session holds (/recording/events): (kind, text), oldest first.
inline std::vector<std::pair<std::string, std::string>> SessionEvents(const daq::Session& session) {
  std::vector<std::pair<std::string, std::string>> out;
  const daq::MetadataGroup* recording = session.find_metadata("recording");
  const daq::MetadataGroup* events = recording ? recording->find_group("events") : nullptr;
  if (events == nullptr) return out;
  for (const daq::MetadataGroup& e : events->groups) out.emplace_back(*e.text("kind"), *e.text("text"));
  return out;
}

}  // namespace strut::test
