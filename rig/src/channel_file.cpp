#include "strut/rig/channel_file.h"

#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <map>

#include "strut/daq/toml_reader.h"

namespace strut::rig {
namespace {

struct UnitScale {
  const char* unit;
  double to_si;
};

struct RecordedChannel {
  const char* name;
  const char* si_unit;
  std::vector<UnitScale> units;  // what a calibration sheet may give, and the factor to SI
  bool required;
};

const std::vector<RecordedChannel>& RecordedChannels() {
  static const std::vector<RecordedChannel> channels = {
      {"stroke", "m", {{"m", 1.0}, {"mm", 1e-3}}, true},
      {"force", "N", {{"N", 1.0}, {"kN", 1e3}}, true},
      {"pressure", "Pa", {{"Pa", 1.0}, {"kPa", 1e3}, {"bar", 1e5}, {"MPa", 1e6}}, false},
  };
  return channels;
}

using Reader = daq::TomlReader<ChannelFileError>;

}  // namespace

ChannelMap ParseChannelFile(std::string_view text, const std::string& source) {
  const Reader r(source);
  const toml::table root = r.Parse(text);
  ChannelMap map;
  for (auto&& [k, v] : root) {
    const bool channel = std::any_of(RecordedChannels().begin(), RecordedChannels().end(),
                                     [&](const RecordedChannel& c) { return k.str() == c.name; });
    if (!channel && k.str() != "module" && k.str() != "frame" && k.str() != "channels")
      r.Fail(v, fmt::format("unknown key '{}' (known: module, frame, channels, [stroke], [force], [pressure])",
                            k.str()));
  }
  const toml::node* module_node = root.get("module");
  if (!module_node) r.Fail("module: the module number (0..63) is needed");
  const std::int64_t module = *r.Integer(root, "", "module");
  if (module < 0 || module > 63) r.Fail(*module_node, fmt::format("module {} is outside 0..63", module));
  map.layout.module = static_cast<std::uint8_t>(module);
  const toml::node* frame_node = root.get("frame");
  if (!frame_node) r.Fail("frame: the frame kind is needed (\"classic\" or \"fd\")");
  const std::string frame = *r.Text(root, "", "frame");
  if (frame != "classic" && frame != "fd") r.Fail(*frame_node, fmt::format("frame \"{}\": give \"classic\" or \"fd\"", frame));
  map.layout.fd = frame == "fd";

  // Each recorded channel: its place in the set and its calibration, converted to SI.
  std::map<std::int64_t, std::pair<daq::ChannelDescriptor, const toml::node*>> placed;
  for (const RecordedChannel& c : RecordedChannels()) {
    const toml::node* node = root.get(c.name);
    if (!node) {
      if (c.required) r.Fail(fmt::format("[{}] is missing: the run records stroke and force", c.name));
      continue;
    }
    const toml::table* t = &r.Table(*node, "", c.name);
    const std::string where = Reader::In(c.name);
    if (std::string_view(c.name) == "pressure")
      r.RefuseUnknown(*t, where, {"index", "unit", "gain", "offset", "range_min", "range_max", "reference"});
    else
      r.RefuseUnknown(*t, where, {"index", "unit", "gain", "offset", "range_min", "range_max"});
    const auto index = r.Integer(*t, where, "index");
    if (!index) r.Fail(*node, where + "index: the channel's 0-based place in the sample set is needed");
    if (*index < 0) r.Fail(*t->get("index"), fmt::format("{}index {} is negative", where, *index));
    const auto unit = r.Text(*t, where, "unit");
    if (!unit) r.Fail(*node, where + "unit: the unit of gain and offset is needed");
    const auto scale = std::find_if(c.units.begin(), c.units.end(), [&](const UnitScale& u) { return *unit == u.unit; });
    if (scale == c.units.end()) {
      std::vector<std::string> known;
      for (const UnitScale& u : c.units) known.emplace_back(u.unit);
      r.Fail(*t->get("unit"), fmt::format("{}unit \"{}\": give one of {}", where, *unit, fmt::join(known, ", ")));
    }
    const auto gain = r.Number(*t, where, "gain");
    if (!gain) r.Fail(*node, where + "gain: units per count are needed");
    if (*gain == 0.0) r.Fail(*t->get("gain"), where + "gain must not be zero");
    daq::Calibration cal;
    cal.gain = *gain * scale->to_si;
    cal.offset = r.Number(*t, where, "offset").value_or(0.0) * scale->to_si;
    const auto lo = r.Number(*t, where, "range_min"), hi = r.Number(*t, where, "range_max");
    if (lo.has_value() != hi.has_value())
      r.Fail(*t->get(lo ? "range_min" : "range_max"), where + "range_min and range_max come together");
    if (lo) {
      if (!(*lo < *hi)) r.Fail(*t->get("range_max"), fmt::format("{}range_max {} must exceed range_min {}", where, *hi, *lo));
      cal.range_min = *lo * scale->to_si;
      cal.range_max = *hi * scale->to_si;
    } else {  // the span of the 16-bit counts
      cal.range_min = std::min(cal.ToSi(-32768), cal.ToSi(32767));
      cal.range_max = std::max(cal.ToSi(-32768), cal.ToSi(32767));
    }
    if (std::string_view(c.name) == "pressure") {
      map.pressure_reference = r.Text(*t, where, "reference").value_or("gauge");
      if (map.pressure_reference != "gauge" && map.pressure_reference != "absolute")
        r.Fail(*t->get("reference"),
               fmt::format("{}reference \"{}\": give \"gauge\" or \"absolute\"", where, map.pressure_reference));
    }
    if (const auto other = placed.find(*index); other != placed.end())
      r.Fail(*t->get("index"), fmt::format("{}index {} is [{}]'s already", where, *index, other->second.first.name));
    placed[*index] = {daq::ChannelDescriptor{c.name, c.si_unit, cal}, t->get("index")};
  }

  const std::int64_t highest = placed.rbegin()->first;
  const std::int64_t channels = r.Integer(root, "", "channels").value_or(highest + 1);
  map.layout.channels = static_cast<int>(std::clamp<std::int64_t>(channels, 0, 1000));
  std::string error;
  if (!map.layout.IsValid(&error)) {
    const toml::node* n = root.get("channels");
    r.Fail(n ? *n : *frame_node, fmt::format("{} frames of {} readings per sample set: {}", frame, channels, error));
  }
  if (highest >= channels) {
    const auto& [descriptor, node] = placed.rbegin()->second;
    r.Fail(*node, fmt::format("[{}] index {} is beyond the {} readings of a sample set (channels = {})",
                              descriptor.name, highest, channels, channels));
  }
  for (int i = 0; i < map.layout.channels; ++i) {
    const auto p = placed.find(i);
    map.channels.push_back(p != placed.end() ? p->second.first
                                             : daq::ChannelDescriptor{fmt::format("channel{}", i), "1", {}});
  }
  return map;
}

ChannelMap ReadChannelFile(const std::string& path) {
  return ParseChannelFile(Reader::ReadFile(path, "the channel file"), path);
}

}  // namespace strut::rig
