// Recorded sessions: the in-memory form of the contract format
// (../shared/reference/session-format.md, version 1) and its HDF5 reader and writer.
#pragma once

#include <cstddef>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

namespace strut::daq {

//! Ambient pressure that gauge readings are relative to (Pa), as the contract defines it.
inline constexpr double kGaugeReferencePa = 101325.0;

//! A user-facing error about a session file. what() names the file, experiment and item.
class SessionError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

//! Session profiles. "damper" is the contract (the default; strut writes no `profile` attribute
//! for it). "generic" is strut's extension for measured records of other systems
//! (docs/session-files.md, "Generic sessions"): channels of any name, periodic experiments with
//! any excitation waveform, and free records (kind "record").
inline constexpr std::string_view kDamperProfile = "damper";
inline constexpr std::string_view kGenericProfile = "generic";

//! kRecord: a free record (generic profile only), e.g. a test signal from rest.
enum class ExperimentKind { kPeriodic, kDrop, kStatic, kRecord };
std::string_view ToString(ExperimentKind kind);

//! One recorded channel: samples in SI units.
struct Channel {
  std::string name;        //!< "stroke", "force", "pressure", or any further channel
  std::string units;       //!< SI unit symbol: "m", "N", "Pa", "K", "s", "V", ...
  std::string reference;   //!< pressure only: "absolute" or "gauge"; empty otherwise
  std::vector<double> samples;
};

//! True for a channel strut's recorder keeps beside the measurements (docs/recording.md): raw
//! counts `<channel>_counts`, the acquisition's `sequence` index and `status` word, all with
//! units "1". Not a measurement: checks of measured signals (dropouts, clipping) skip it.
bool IsRecordingChannel(const Channel& channel);

//! One experiment (/experiments/<label>).
struct Experiment {
  std::string label;
  ExperimentKind kind = ExperimentKind::kPeriodic;
  std::string status = "complete";  //!< "complete" or "aborted"
  double sample_rate = 0.0;         //!< Hz

  // periodic only
  double frequency = 0.0;        //!< Hz
  double amplitude = 0.0;        //!< m (generic profile: optional, 0 when not applicable)
  double static_position = 0.0;  //!< m (generic profile: optional, 0 when not applicable)
  std::string waveform = "sine";  //!< "sine" (generic profile: any name, e.g. "multisine")
  long periods = 0;              //!< whole periods recorded in steady state
  std::string group;             //!< optional: "high", "middle", "low"

  // drop only
  double drop_mass = 0.0;        //!< kg
  double impact_velocity = 0.0;  //!< m/s

  std::vector<double> time;       //!< s, from 0
  std::vector<Channel> channels;  //!< in file order; stroke, force, pressure and any further ones

  //! Further attributes found in the file that the contract does not define (kept on rewrite).
  std::map<std::string, std::string> extra_attributes;

  std::size_t sample_count() const { return time.size(); }
  const Channel* find_channel(std::string_view name) const;
  //! The channel, or SessionError naming the experiment and channel.
  const Channel& channel(std::string_view name) const;
  //! Pressure samples as absolute pressure (Pa), whatever the recorded reference.
  std::vector<double> absolute_pressure() const;
  //! Samples per period (periodic experiments): sample_rate / frequency.
  double samples_per_period() const { return sample_rate / frequency; }
};

//! Relative tolerance within which sample_rate / frequency is a whole number of samples per
//! period. Far above the rounding of a rate and frequency given in decimal (about 1e-15), and far
//! below a drift that matters: phase-synchronous averaging over P periods of n samples is off by
//! at most 1e-9 * P * n samples (a thousandth of a sample over 1000 periods of 1000 samples).
inline constexpr double kWholeSamplesTolerance = 1e-9;

//! sample_rate / frequency when it is a whole number of at least `minimum` samples (within
//! kWholeSamplesTolerance, relative), else nullopt; nullopt too when either is not positive.
//! The one test for "whole samples per period": the generators, the rig and the fit use it alike.
std::optional<long> WholeSamplesPerPeriod(double sample_rate, double frequency, long minimum = 1);

//! The value of an attribute of an extra group: a number (float64), a whole number (int64) or a
//! text (fixed-length string), written with that HDF5 type and read back as the same alternative.
using AttributeValue = std::variant<double, long long, std::string>;

//! An extra group under the root that the contract leaves to the project (e.g. `/truth` of a
//! simulated session, docs/session-files.md): attributes and subgroups only; kept on rewrite.
struct MetadataGroup {
  std::string name;                                   //!< link name, no '/'
  std::map<std::string, AttributeValue> attributes;  //!< by name
  std::vector<MetadataGroup> groups;                  //!< subgroups, in file order

  //! The subgroup of that name, or nullptr.
  const MetadataGroup* find_group(std::string_view group_name) const;
  //! The attribute as a number (a double or a whole number), or nullopt when absent or a text.
  std::optional<double> number(std::string_view attribute) const;
  //! The attribute as a text, or nullopt when absent or a number.
  std::optional<std::string> text(std::string_view attribute) const;
};

//! A whole recorded session (one HDF5 file).
struct Session {
  std::string source_path;  //!< where it was read from (for messages); empty when built in memory
  int format_version = 1;
  std::string created_utc;
  std::string damper_serial;
  std::string rig;
  std::string profile = std::string(kDamperProfile);  //!< kDamperProfile or kGenericProfile
  std::vector<Experiment> experiments;
  //! Extra root groups other than /experiments (strut's own metadata), in file order.
  std::vector<MetadataGroup> metadata;

  bool generic() const { return profile == kGenericProfile; }

  const Experiment* find_experiment(std::string_view label) const;
  //! The experiment, or SessionError naming the file and label.
  const Experiment& experiment(std::string_view label) const;
  //! The extra root group of that name, or nullptr.
  const MetadataGroup* find_metadata(std::string_view name) const;
};

//! Options for writing a session file.
struct WriteOptions {
  int gzip_level = 4;            //!< 0 = no compression
  std::size_t chunk_samples = 0; //!< 0 = contiguous when uncompressed, automatic chunks otherwise
};

//! Reads and validates a session file. Throws SessionError with the file, experiment and item
//! for every defect: not HDF5 or truncated, missing attribute or channel, wrong types,
//! lengths that differ, NaN/Inf samples, sample count that does not match `periods`, unknown units.
Session ReadSession(const std::string& path);

//! Checks an in-memory session against the contract; returns one message per defect (empty = valid).
std::vector<std::string> Validate(const Session& session);

//! Writes the session crash-safely: to `path + ".partial"`, flushed and closed, then renamed.
//! Throws SessionError on I/O failure or when the session does not validate.
void WriteSession(const std::string& path, const Session& session, const WriteOptions& options = {});

//! Current time as ISO 8601 UTC ("2026-11-22T05:32:50Z").
std::string UtcNowIso8601();
//! Seconds since the epoch of an ISO 8601 UTC time ("2026-11-22T05:32:50Z", fractional seconds
//! allowed); nullopt when the text is not one.
std::optional<double> ParseUtcIso8601(const std::string& text);

//! When each experiment of `session` was recorded, as a fraction of the session: 0 the first, 1 the
//! last, in the order of `session.experiments`. From the experiments' `started_utc` attributes
//! (what strut's rig writes) where every experiment has a readable one and they span some time;
//! else from their order in the file (the recorded order: creation order where the file tracks it).
//! A session of one experiment gives {0}. A gas charge that leaks over a session drifts with it.
std::vector<double> ExperimentSessionTimes(const Session& session);
//! The session time of the `index`-th of `count` experiments by their order alone: index / (count - 1),
//! 0 for a single experiment.
double OrderSessionTime(std::size_t index, std::size_t count);

//! A transducer zero the lab measured before the test, and the sd it is known to (SI units).
struct MeasuredZero {
  double value = 0.0, sd = 0.0;
};

//! The transducer zeros a session records in its optional root group `/calibration`
//! (docs/session-files.md): `load_cell_zero` and `load_cell_zero_sd` (N: the force reading less the
//! force, as found with the load cell unloaded), `stroke_zero` and `stroke_zero_sd` (m: the stroke
//! reading at full extension, as the top-out reference finds it). Either pair may be absent.
struct RecordedZeros {
  std::optional<MeasuredZero> load_cell, stroke;
  bool empty() const { return !load_cell && !stroke; }
};

//! The zeros `session` records; none when it has no `/calibration` group. Throws SessionError
//! naming the file and the attribute when a zero is not a finite number, or its sd is missing, not
//! a number or not positive.
RecordedZeros ReadRecordedZeros(const Session& session);
//! Records `zeros` in `session.metadata` as the `/calibration` group (replacing an earlier one; no
//! group when `zeros` is empty).
void RecordZeros(const RecordedZeros& zeros, Session& session);

}  // namespace strut::daq
