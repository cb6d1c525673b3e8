// The one place where a session is checked against the contract (private to daq). The HDF5
// reader reports what only a file can get wrong (missing attribute, wrong type, not 1-D) into the
// same DefectList, then runs CheckSession on what it read; Validate runs CheckSession alone.
#pragma once

#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "strut/daq/session.h"

namespace strut::daq::detail {

//! Defect messages of one file, each "<file>: experiment '<label>': <item>: <what>".
class DefectList {
 public:
  explicit DefectList(std::string file) : file_(std::move(file)) {}

  //! Adds a defect; an empty `experiment` means the file (root) level.
  void Add(std::string_view experiment, std::string_view item, std::string_view what);
  //! True when a defect about this experiment and item was added already: later checks of the
  //! same item would only repeat it (a missing attribute reads as 0, which is also "not > 0").
  bool Has(std::string_view experiment, std::string_view item) const;
  //! Logs a warning with the same prefix (a slight oddity that does not make the file invalid).
  void Warn(std::string_view experiment, std::string_view item, std::string_view what) const;

  const std::string& file() const { return file_; }
  bool empty() const { return messages_.empty(); }
  const std::vector<std::string>& messages() const { return messages_; }
  //! All messages, one per line.
  std::string Joined() const;

 private:
  std::string Prefix(std::string_view experiment, std::string_view item) const;

  std::string file_;
  std::vector<std::string> messages_;
  std::set<std::pair<std::string, std::string>> items_;
};

//! Checks everything the contract says about values: attribute ranges, units, lengths, samples,
//! time axis, periods. Skips items the reader already reported.
void CheckSession(const Session& session, DefectList& defects);

//! Item names shared by the reader and the checker, so Has() matches.
std::string AttributeItem(std::string_view name);
std::string ChannelItem(std::string_view name);
std::string ChannelAttributeItem(std::string_view channel, std::string_view attribute);
inline constexpr std::string_view kTimeItem = "dataset 'time'";
inline constexpr std::string_view kTimeUnitsItem = "dataset 'time': attribute 'units'";
inline constexpr std::string_view kSamplesItem = "samples";
inline constexpr std::string_view kExperimentsItem = "group '/experiments'";

//! The three channels every experiment has, in the order channels are listed.
inline constexpr std::string_view kStandardChannels[] = {"stroke", "force", "pressure"};
//! SI units the channel must have, or empty for a further channel.
std::string_view ExpectedUnits(std::string_view channel);
//! True for the accepted SI unit symbols (m, N, Pa, K, s, V, A, m/s, m/s^2, m/s2, kg, 1).
bool IsKnownUnit(std::string_view units);

//! Attribute names the writer writes for an experiment of this kind; anything else found in a
//! file goes to extra_attributes.
bool IsContractAttribute(ExperimentKind kind, std::string_view name);

//! The defect when `samples` do not cover e.periods whole periods (contract: length = periods *
//! sample_rate / frequency, ±1 accepted), else nullopt. Needs sample_rate and frequency > 0.
std::optional<std::string> PeriodCountDefect(const Experiment& e, std::size_t samples);

//! Sorts channels: stroke, force, pressure, then the others by name.
void SortChannels(std::vector<Channel>& channels);

}  // namespace strut::daq::detail
