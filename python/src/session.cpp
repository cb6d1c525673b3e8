// Sessions into Python data through daq's session reader (daq::ReadSession): the same reader and
// the same checks as every strut command.
#include <pybind11/stl.h>

#include "bindings.h"

namespace strut::python {
namespace {

py::object AttributeToPython(const daq::AttributeValue& value) {
  return std::visit([](const auto& v) -> py::object { return py::cast(v); }, value);
}

py::dict GroupToPython(const daq::MetadataGroup& group) {
  py::dict d;
  for (const auto& [name, value] : group.attributes) d[py::str(name)] = AttributeToPython(value);
  for (const daq::MetadataGroup& sub : group.groups) d[py::str(sub.name)] = GroupToPython(sub);
  return d;
}

py::dict ExperimentToPython(const daq::Experiment& e) {
  py::dict d;
  d["label"] = e.label;
  d["kind"] = std::string(daq::ToString(e.kind));
  d["status"] = e.status;
  d["sample_rate"] = e.sample_rate;
  d["frequency"] = e.frequency;
  d["amplitude"] = e.amplitude;
  d["static_position"] = e.static_position;
  d["waveform"] = e.waveform;
  d["periods"] = e.periods;
  d["group"] = e.group;
  d["drop_mass"] = e.drop_mass;
  d["impact_velocity"] = e.impact_velocity;
  d["extra_attributes"] = e.extra_attributes;
  d["time"] = Array(e.time);
  py::list channels;
  for (const daq::Channel& c : e.channels) {
    py::dict channel;
    channel["name"] = c.name;
    channel["units"] = c.units;
    channel["reference"] = c.reference;
    channel["samples"] = Array(c.samples);
    channels.append(channel);
  }
  d["channels"] = channels;
  return d;
}

}  // namespace

py::array_t<double> Array(const std::vector<double>& values) {
  return py::array_t<double>(static_cast<py::ssize_t>(values.size()), values.data());
}

py::dict SessionToPython(const daq::Session& session) {
  py::dict d;
  d["source_path"] = session.source_path;
  d["format_version"] = session.format_version;
  d["created_utc"] = session.created_utc;
  d["damper_serial"] = session.damper_serial;
  d["rig"] = session.rig;
  d["profile"] = session.profile;
  py::dict metadata;
  for (const daq::MetadataGroup& g : session.metadata) metadata[py::str(g.name)] = GroupToPython(g);
  d["metadata"] = metadata;
  py::list experiments;
  for (const daq::Experiment& e : session.experiments) experiments.append(ExperimentToPython(e));
  d["experiments"] = experiments;
  return d;
}

void AddSessionFunctions(py::module_& m) {
  m.def(
      "read_session",
      [](const std::string& path) {
        daq::Session session;
        {
          py::gil_scoped_release unlocked;
          session = daq::ReadSession(path);
        }
        return SessionToPython(session);
      },
      py::arg("path"), "Reads and validates a session file (daq::ReadSession) into plain Python data.");
}

}  // namespace strut::python
