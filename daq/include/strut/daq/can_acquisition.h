// The acquisition module over CAN: the frame layout (docs/can-acquisition.md), the module's side
// (CanSampleEncoder, CanAcquisitionSender) and strut's side (CanStreamDecoder, CanAcquisition).
//
// Frames (29-bit extended ids, little-endian payloads):
//   id = kind << 24 | module << 18 | field
//   sample frame (kind 0x08): field = index of its first sample set mod 2^18; payload = sets x
//     channels x int16 counts (set-major). Classic: 1 set of 4 channels in 8 bytes. FD: 8 sets in 64.
//   status frame (kind 0x04, classic, 8 bytes): u32 index of the next sample set, u16 status
//     word, u8 transmit and u8 receive error counters of the module's controller.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "strut/daq/acquisition.h"
#include "strut/daq/can_transport.h"

namespace strut::daq {

//! How samples are packed into frames.
struct CanFrameLayout {
  int channels = 4;       //!< readings per sample set, 16 bits each
  bool fd = false;        //!< CAN FD frames of up to 64 bytes, else classic frames of up to 8
  std::uint8_t module = 1;  //!< module number 0..63, part of every id

  static constexpr std::uint32_t kSampleKind = 0x08;
  static constexpr std::uint32_t kStatusKind = 0x04;
  static constexpr int kSequenceBits = 18;
  static constexpr std::uint32_t kSequenceMask = (1u << kSequenceBits) - 1;

  //! Sample sets in one sample frame: classic 8 / (2 channels), FD 64 / (2 channels).
  int sets_per_frame() const;
  //! Payload bytes of a sample frame: sets x channels x 2, rounded up to a CAN FD length.
  int sample_payload() const;
  canid_t sample_id(std::uint64_t first_index) const;
  canid_t status_id() const;
  //! False with a message when channels or module are out of range (1..4 classic, 1..32 FD; 0..63).
  bool IsValid(std::string* error) const;
};

//! Module status word (status frame bytes 4-5). Fault bits make the data invalid.
namespace can_status {
inline constexpr std::uint16_t kAdcOverRange = 1u << 0;    //!< a channel at its ADC limit
inline constexpr std::uint16_t kAdcFault = 1u << 1;        //!< fault
inline constexpr std::uint16_t kExcitationFault = 1u << 2; //!< transducer supply out of tolerance: fault
inline constexpr std::uint16_t kBufferOverflow = 1u << 3;  //!< the module dropped samples (shows as a gap)
inline constexpr std::uint16_t kErrorPassive = 1u << 4;    //!< the module's own controller is error-passive
inline constexpr std::uint16_t kSimulated = 1u << 15;      //!< a simulated module
inline constexpr std::uint16_t kFaultMask = kAdcFault | kExcitationFault | kErrorPassive;
}  // namespace can_status

//! Bus bit rates: the nominal (arbitration) rate and, for CAN FD with bit-rate switching, the data phase.
struct CanBitrates {
  double nominal = 1e6;  //!< bit/s
  double data = 5e6;     //!< bit/s, CAN FD data phase
};

//! The bits of one frame on the wire, split into the phases that run at each bit rate.
struct CanFrameBits {
  int nominal = 0;  //!< bits at the nominal rate (all of a classic frame)
  int data = 0;     //!< bits at the data rate (CAN FD with bit-rate switch)
  double Seconds(const CanBitrates& rates) const { return nominal / rates.nominal + data / rates.data; }
};
//! Bits of a data frame with a 29-bit id and `payload` bytes, with the worst-case stuffing
//! (`worst_case`) or none, including the 3-bit interframe space. docs/can-acquisition.md.
CanFrameBits FrameBits(bool fd, int payload, bool worst_case);
//! Sample sets per second of `layout` at `bus_load` (0..1) of the bus, worst-case stuffing,
//! with one status frame every `status_every` sample sets.
double MaxSampleRate(const CanFrameLayout& layout, const CanBitrates& rates, double bus_load, int status_every);
//! Sample sets between a module's status frames at `sample_rate`: ten status frames a second.
inline int StatusEvery(double sample_rate) { return std::max(1, static_cast<int>(std::lround(sample_rate / 10))); }

//! The module's side: sample sets (counts) into frames, and status frames.
class CanSampleEncoder {
 public:
  //! Throws std::invalid_argument when the layout is invalid.
  explicit CanSampleEncoder(CanFrameLayout layout);
  const CanFrameLayout& layout() const { return layout_; }
  //! Adds one sample set (`layout.channels` counts); appends a frame to `out` when one is full.
  void Add(std::span<const std::int16_t> set, std::vector<CanFrame>& out);
  //! Appends a status frame carrying the index of the next set to be sent.
  void AddStatus(std::uint16_t status_word, std::uint8_t tx_errors, std::uint8_t rx_errors,
                 std::vector<CanFrame>& out) const;
  //! Index of the next sample set (sets added so far).
  std::uint64_t next_index() const { return next_index_; }
  //! Skips `sets` sample sets without sending them (the module lost them: tests, fault injection).
  void Skip(std::uint64_t sets);

 private:
  CanFrameLayout layout_;
  std::uint64_t next_index_ = 0;
  std::vector<std::int16_t> pending_;  //!< counts of the frame being filled
};

//! Options of the receiving side.
struct CanAcquisitionOptions {
  CanFrameLayout layout;
  double sample_rate = 2000.0;  //!< sample sets per second the module sends (nominal)
  std::vector<ChannelDescriptor> channels;  //!< one per layout channel, in frame order
  //! The stream is frozen when no frame arrives for this long: a few status periods.
  std::chrono::nanoseconds stale_after = std::chrono::milliseconds(250);
  //! Sample sets per block Read returns when the stream flows (0: sample_rate / 100, at least 1).
  std::size_t block_sets = 0;
  //! False with a message naming the item when something is inconsistent.
  bool IsValid(std::string* error) const;
};

//! strut's side without I/O: decodes frames into blocks, keeps the stream's state (sequence,
//! bus state, module status) and counts what is wrong. Survives any input.
class CanStreamDecoder {
 public:
  //! Throws std::invalid_argument when the options are invalid.
  explicit CanStreamDecoder(CanAcquisitionOptions options);
  const CanAcquisitionOptions& options() const { return options_; }
  //! Forgets the stream: indices from 0, counters to zero, bus error-active, no module status.
  void Reset(std::int64_t now_ns);
  //! Feeds one frame received at `received_ns` into `block`. Returns false, without consuming
  //! the frame, when it would start a new block (a gap or a change of validity while `block`
  //! already holds samples): return `block` and feed the frame again into a fresh one.
  bool Feed(const CanFrame& frame, std::int64_t received_ns, AcquiredBlock& block);
  //! Marks `block` stale when nothing arrived for stale_after before `now_ns`.
  void CheckStale(std::int64_t now_ns, AcquiredBlock& block);
  //! Counts transport units that were no frame at all.
  void AddMalformed(std::uint64_t count, std::int64_t now_ns, AcquiredBlock& block);
  //! Counts frames the receiving socket dropped.
  void AddReceiverDrops(std::uint64_t count, std::int64_t now_ns, AcquiredBlock& block);
  //! Ends a block: the corrupt-frame and bus-error events gathered while it was read.
  void Finish(AcquiredBlock& block);
  const AcquisitionStats& stats() const { return stats_; }
  //! Quality flags of the stream's current state (bus and module status).
  std::uint32_t state_flags() const;
  std::uint64_t next_index() const { return next_index_; }

 private:
  void Event(AcquiredBlock& block, AcquisitionEvent::Kind kind, std::int64_t t, std::uint64_t count, std::string text);
  void FeedError(const CanFrame& frame, std::int64_t t, AcquiredBlock& block);
  void FeedStatus(const CanFrame& frame, std::int64_t t, AcquiredBlock& block);
  bool FeedSamples(const CanFrame& frame, std::int64_t t, AcquiredBlock& block);
  void Corrupt(AcquiredBlock& block, std::uint64_t& counter, std::int64_t t, const char* what);
  //! A frame from the module arrived: the stream is alive (ends a stale period).
  void Alive(std::int64_t t, AcquiredBlock& block);
  //! Sets the clock says the module sampled beyond `base` by the time `t` a frame starting
  //! at `base` arrived (the linear time rule).
  double ClockSets(std::int64_t t, std::uint64_t base) const;
  //! How far (in sets) a frame may run ahead of ClockSets before it is refused.
  double ClockTolerance(std::int64_t t) const;

  CanAcquisitionOptions options_;
  int sets_per_frame_ = 1;
  double period_ns_ = 0.0;
  AcquisitionStats stats_;
  bool started_ = false;           //!< a sample frame has arrived since Reset
  std::uint64_t next_index_ = 0;   //!< index of the next expected sample set
  std::uint64_t pending_lost_ = 0; //!< sets a status frame showed lost, charged to the next sample frame
  std::uint32_t seq_offset_ = 0;   //!< the module's sequence of our set 0
  int consecutive_out_of_step_ = 0;  //!< sample frames behind the stream or ahead of the clock in a row
  static constexpr int kResyncAfterFrames = 16;
  std::int64_t anchor_ns_ = 0;     //!< monotonic time of sample set 0 (linear time rule)
  std::int64_t last_frame_ns_ = 0;
  bool stale_ = false;
  bool have_device_base_ = false;
  std::uint32_t device_base_ = 0;  //!< the module's 32-bit index of our set 0
  bool bus_off_ = false, error_passive_ = false;
  std::uint16_t device_status_ = 0;
  bool have_device_status_ = false;
  // Per block: what was dropped while it was read (one event each, not one per frame).
  std::uint64_t block_corrupt_ = 0, block_bus_errors_ = 0;
  std::int64_t block_corrupt_ns_ = 0, block_bus_errors_ns_ = 0;
  std::string block_corrupt_what_;
};

//! The acquisition module over a CAN transport.
class CanAcquisition : public AcquisitionModule {
 public:
  //! Throws std::invalid_argument when the options are invalid.
  CanAcquisition(std::unique_ptr<CanTransport> transport, CanAcquisitionOptions options);
  const StreamDescription& description() const override { return description_; }
  void Start() override;
  void Stop() override;
  AcquiredBlock Read(std::chrono::nanoseconds timeout) override;
  const AcquisitionStats& stats() const override { return decoder_.stats(); }
  CanTransport& transport() { return *transport_; }

 private:
  std::unique_ptr<CanTransport> transport_;
  CanStreamDecoder decoder_;
  StreamDescription description_;
  std::size_t block_sets_ = 1;
  bool running_ = false;
  std::vector<CanFrame> batch_;
  std::size_t batch_pos_ = 0, batch_size_ = 0;
  std::int64_t batch_time_ns_ = 0;
  CanTransportCounters seen_;
};

//! The module's side on a transport: sample sets in, frames out, a status frame every
//! `status_every` sets (the heartbeat the receiver's stale check relies on).
class CanAcquisitionSender {
 public:
  CanAcquisitionSender(std::unique_ptr<CanTransport> transport, CanFrameLayout layout, int status_every);
  //! Queues one set of counts; sends when `flush_sets` sets are queued (batches of datagrams).
  void Add(std::span<const std::int16_t> set);
  //! Sends what is queued (whole frames; a partly filled FD frame waits for its remaining sets).
  void Flush();
  void set_status(std::uint16_t word) { status_ = word; }
  void set_error_counters(std::uint8_t tx, std::uint8_t rx) { tx_errors_ = tx, rx_errors_ = rx; }
  //! Sends a status frame now.
  void SendStatus();
  CanSampleEncoder& encoder() { return encoder_; }
  const CanSampleEncoder& encoder() const { return encoder_; }
  CanTransport& transport() { return *transport_; }
  std::size_t flush_sets = 64;
  std::chrono::nanoseconds send_timeout = std::chrono::milliseconds(500);

 private:
  std::unique_ptr<CanTransport> transport_;
  CanSampleEncoder encoder_;
  int status_every_;
  std::uint16_t status_ = 0;
  std::uint8_t tx_errors_ = 0, rx_errors_ = 0;
  std::vector<CanFrame> queue_;
  std::size_t queued_sets_ = 0;
};

}  // namespace strut::daq
