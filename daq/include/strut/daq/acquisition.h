// The acquisition module: the device kind that samples the rig's transducers (stroke, force,
// pressure, ...) and streams them to strut. One small interface, with a real implementation over
// CAN (can_acquisition.h) and simulated or replayed ones behind the same interface.
//
// What the caller sees (docs/can-acquisition.md, "What the caller sees"):
// - Read(timeout) returns an AcquiredBlock: a run of consecutive sample sets (one reading per
//   channel) with one quality. A block never spans a sequence gap or a change of validity: the
//   block after a gap carries the number of lost sample sets and the kSequenceGap flag.
// - Every sample has a monotonic timestamp (CLOCK_MONOTONIC, ns); every block carries a
//   monotonic-to-UTC pair taken when it was read, so a recorder can store the mapping.
// - Bus-off, error-passive and a device fault mark the block invalid (Quality::valid() false);
//   the samples are still delivered, so nothing is lost, only marked.
// - A frozen stream (no frame within `stale_after`) gives blocks with kStale and no samples.
// - Errors that end the stream (the transport cannot be opened or fails) throw daq::DeviceError,
//   the one error type of the device drivers, naming the source and the errno text.
#pragma once

#include <chrono>
#include <cstdint>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "strut/daq/device_error.h"

namespace strut::daq {


//! Raw ADC counts to SI: value = offset + gain * counts, calibrated over [range_min, range_max]
//! (in SI). After openDAQ's post-scaling: the counts travel, the SI value is derived.
struct Calibration {
  double gain = 1.0;    //!< SI units per count
  double offset = 0.0;  //!< SI value at zero counts
  double range_min = -std::numeric_limits<double>::max();  //!< SI, lowest calibrated reading
  double range_max = std::numeric_limits<double>::max();   //!< SI, highest calibrated reading

  //! The calibration that maps the whole signed 16-bit span [-32768, 32767] onto [min, max].
  static Calibration FromRange16(double min, double max);

  double ToSi(std::int32_t counts) const { return offset + gain * static_cast<double>(counts); }
  //! The nearest count for an SI value, saturated to the signed 16-bit span (the sender's side).
  std::int16_t ToCounts16(double si) const;
  //! True when `si` is inside [range_min, range_max].
  bool InRange(double si) const { return si >= range_min && si <= range_max; }
  //! False with a message when gain is zero or not finite, offset not finite, or min >= max.
  bool IsValid(std::string* error) const;
};

//! One sampled channel: what it is, in which unit, and how counts become SI.
struct ChannelDescriptor {
  std::string name;       //!< "stroke", "force", "pressure", ...
  std::string unit;       //!< SI unit symbol of the calibrated value: "m", "N", "Pa"
  Calibration calibration;
};

//! A monotonic time and the UTC time read as close to it as the clocks allow.
struct TimePair {
  std::int64_t monotonic_ns = 0;  //!< CLOCK_MONOTONIC
  std::int64_t utc_ns = 0;        //!< CLOCK_REALTIME, ns since 1970-01-01T00:00:00Z
};
//! Now on both clocks: the UTC read is bracketed by two monotonic reads, the tightest of a few
//! tries kept, and the monotonic time is the middle of its bracket.
TimePair NowTimePair();
//! CLOCK_MONOTONIC now, ns.
std::int64_t MonotonicNs();

//! Quality of a block: a set of flags. valid() is false when the data must not be used.
struct Quality {
  enum Flag : std::uint32_t {
    kSequenceGap = 1u << 0,    //!< a discontinuity before this block: lost_before sets lost, or a resynchronisation
    kOverRange = 1u << 1,      //!< a reading at the ADC limits or outside its calibrated range
    kErrorPassive = 1u << 2,   //!< the receiver or the module was error-passive: data invalid
    kBusOff = 1u << 3,         //!< the receiver's controller was bus-off: data invalid
    kDeviceFault = 1u << 4,    //!< the module's status word reports a fault: data invalid
    kStale = 1u << 5,          //!< no frame within stale_after: the stream is frozen
    kCorruptFrames = 1u << 6,  //!< malformed frames were dropped while this block was read
    kBusErrors = 1u << 7,      //!< error frames (protocol errors, warnings): data still valid
  };
  static constexpr std::uint32_t kInvalidMask = kErrorPassive | kBusOff | kDeviceFault;

  std::uint32_t flags = 0;
  bool has(Flag f) const { return (flags & f) != 0; }
  bool valid() const { return (flags & kInvalidMask) == 0; }
  //! "good" or the flag names joined by '|', e.g. "sequence-gap|bus-off".
  std::string ToString() const;
};

//! Something the stream went through, kept for the session's event log.
struct AcquisitionEvent {
  enum class Kind {
    kSequenceGap,     //!< sample sets lost (count: how many)
    kCorruptFrames,   //!< malformed frames dropped (count; text says which defects)
    kBusErrors,       //!< error frames: protocol errors, warnings, lost arbitration (count)
    kErrorPassive,    //!< entered error-passive
    kBusOff,          //!< entered bus-off
    kBusRecovered,    //!< back to error-active (after error-passive or a restart after bus-off)
    kDeviceStatus,    //!< the module's status word changed (count: the new word)
    kStale,           //!< no frame within stale_after
    kResumed,         //!< frames again after a stale period
    kReceiverDrops,   //!< the receiving socket's queue overflowed (count: datagrams/frames)
    kResynchronised,  //!< the module's sequence jumped (a restart); indices continue (count: the jump mod 2^18)
  };
  Kind kind;
  std::int64_t monotonic_ns = 0;  //!< when strut saw it
  std::uint64_t sample_index = 0; //!< the next sample set's index at that moment
  std::uint64_t count = 0;
  std::string text;               //!< for the log: what happened, with numbers
};
std::string_view ToString(AcquisitionEvent::Kind kind);

//! A run of consecutive sample sets with one quality. Channel-major arrays, all of length size().
struct AcquiredBlock {
  std::uint64_t first_index = 0;   //!< index of the first sample set since Start (lost sets keep their indices)
  std::uint64_t lost_before = 0;   //!< sample sets lost between the previous block and this one
  Quality quality;
  std::vector<std::int64_t> time_ns;               //!< monotonic timestamp of each sample set
  std::vector<std::vector<std::int32_t>> counts;   //!< raw ADC counts, per channel
  std::vector<std::vector<double>> values;         //!< calibrated SI values, per channel
  std::vector<AcquisitionEvent> events;            //!< what happened while this block was read
  std::int64_t last_frame_ns = 0;  //!< monotonic time the last frame of this block arrived (0: none)
  TimePair clock;                  //!< monotonic-to-UTC pair taken when the block was returned

  std::size_t size() const { return time_ns.size(); }
  bool empty() const { return time_ns.empty(); }
};

//! Counters since Start: what arrived and what went wrong.
struct AcquisitionStats {
  std::uint64_t frames = 0;          //!< frames fed to the decoder, good or not
  std::uint64_t status_frames = 0;   //!< good status frames
  std::uint64_t sample_sets = 0;     //!< sample sets delivered
  std::uint64_t lost_sample_sets = 0;
  std::uint64_t gaps = 0;            //!< sequence gaps (each may lose many sets)
  std::uint64_t corrupt_frames = 0;  //!< malformed frames of every kind below
  std::uint64_t wrong_length = 0;    //!< known id, wrong payload length or classic/FD mismatch
  std::uint64_t unknown_id = 0;      //!< not one of the module's ids (or standard, or remote frames)
  std::uint64_t late_frames = 0;     //!< sample frames older than the stream (duplicates, reordered)
  std::uint64_t ahead_of_clock = 0;  //!< sequence or index further ahead than the time since allows
  std::uint64_t resyncs = 0;         //!< times the module's sequence jumped back and was followed
  std::uint64_t malformed_datagrams = 0;  //!< transport units that are no CAN frame at all
  std::uint64_t error_frames = 0;    //!< good error frames (SocketCAN's CAN_ERR_FLAG frames)
  std::uint64_t invalid_sample_sets = 0;  //!< delivered in blocks marked invalid
  std::uint64_t receiver_drops = 0;  //!< frames the receiving socket dropped (SO_RXQ_OVFL)
  std::uint64_t stale_periods = 0;
};

//! What a module streams.
struct StreamDescription {
  std::string source;   //!< names the module in messages, e.g. "udp:127.0.0.1:5000 module 1"
  double sample_rate = 0.0;  //!< sample sets per second (nominal)
  std::vector<ChannelDescriptor> channels;
};

//! The acquisition module interface. Not thread-safe: one thread owns a module and calls
//! Start, Read and Stop.
class AcquisitionModule {
 public:
  virtual ~AcquisitionModule() = default;
  virtual const StreamDescription& description() const = 0;
  //! Starts a stream: counters to zero, indices from 0, whatever was queued before is discarded.
  virtual void Start() = 0;
  //! Stops the stream; Read afterwards throws DeviceError.
  virtual void Stop() = 0;
  //! Waits at most `timeout` and returns what arrived: a full block (the module's block size),
  //! a shorter one when the quality changes, a gap occurs or the timeout passes, or an empty
  //! one. Never waits longer than `timeout`.
  //! @pre Start() was called.
  virtual AcquiredBlock Read(std::chrono::nanoseconds timeout) = 0;
  virtual const AcquisitionStats& stats() const = 0;
};

}  // namespace strut::daq
