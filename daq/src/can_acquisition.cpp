// The CAN acquisition module: frame layout and bus arithmetic, the module's encoder and sender,
// and strut's decoder and AcquisitionModule. docs/can-acquisition.md.
#include "strut/daq/can_acquisition.h"

#include "strut/daq/device_error.h"

#include <fmt/format.h>
#include <linux/can/error.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>

namespace strut::daq {
namespace {

std::uint16_t Le16(const std::uint8_t* p) { return static_cast<std::uint16_t>(p[0] | (p[1] << 8)); }
std::uint32_t Le32(const std::uint8_t* p) {
  return static_cast<std::uint32_t>(p[0]) | (static_cast<std::uint32_t>(p[1]) << 8) |
         (static_cast<std::uint32_t>(p[2]) << 16) | (static_cast<std::uint32_t>(p[3]) << 24);
}
void PutLe16(std::uint8_t* p, std::uint16_t v) {
  p[0] = static_cast<std::uint8_t>(v);
  p[1] = static_cast<std::uint8_t>(v >> 8);
}
void PutLe32(std::uint8_t* p, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}

//! The smallest CAN FD payload length that holds `bytes`.
int FdLength(int bytes) {
  for (const int len : {0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64})
    if (len >= bytes) return len;
  return 64;
}

std::string StatusText(std::uint16_t word) {
  static constexpr std::pair<std::uint16_t, const char*> kBits[] = {
      {can_status::kAdcOverRange, "ADC over-range"},     {can_status::kAdcFault, "ADC fault"},
      {can_status::kExcitationFault, "excitation fault"}, {can_status::kBufferOverflow, "buffer overflow"},
      {can_status::kErrorPassive, "module error-passive"}, {can_status::kSimulated, "simulated"}};
  std::string s;
  for (const auto& [bit, name] : kBits)
    if (word & bit) {
      if (!s.empty()) s += ", ";
      s += name;
    }
  return fmt::format("0x{:04x} ({})", word, s.empty() ? "ok" : s);
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Layout and bus arithmetic

int CanFrameLayout::sets_per_frame() const { return (fd ? CANFD_MAX_DLEN : CAN_MAX_DLEN) / (2 * channels); }

int CanFrameLayout::sample_payload() const {
  const int bytes = sets_per_frame() * channels * 2;
  return fd ? FdLength(bytes) : bytes;
}

canid_t CanFrameLayout::sample_id(std::uint64_t first_index) const {
  return CAN_EFF_FLAG | (kSampleKind << 24) | (static_cast<canid_t>(module) << 18) |
         static_cast<canid_t>(first_index & kSequenceMask);
}

canid_t CanFrameLayout::status_id() const { return CAN_EFF_FLAG | (kStatusKind << 24) | (static_cast<canid_t>(module) << 18); }

bool CanFrameLayout::IsValid(std::string* error) const {
  std::string why;
  const int max_channels = fd ? 32 : 4;
  if (channels < 1 || channels > max_channels)
    why = fmt::format("{} channels: a {} frame carries 1 to {} channels of 16 bits", channels, fd ? "CAN FD" : "classic CAN",
                      max_channels);
  else if (module > 63)
    why = fmt::format("module {} is outside 0..63 (6 bits of the id)", module);
  if (why.empty()) return true;
  if (error) *error = why;
  return false;
}

CanFrameBits FrameBits(bool fd, int payload, bool worst_case) {
  // Worst-case stuffing: one stuff bit after every 4 bits of the stuffed region (the first bit
  // starts a run of 5), i.e. floor((n - 1) / 4) for n bits.
  const auto stuff = [worst_case](int n) { return worst_case ? (n - 1) / 4 : 0; };
  const int data_bits = 8 * payload;
  if (!fd) {
    // SOF, base id 11, SRR, IDE, id extension 18, RTR, r1, r0, DLC 4, data, CRC 15: stuffed.
    const int stuffed = 1 + 11 + 1 + 1 + 18 + 1 + 2 + 4 + data_bits + 15;
    // CRC delimiter, ACK slot and delimiter, EOF 7, interframe space 3: not stuffed.
    return {stuffed + stuff(stuffed) + 13, 0};
  }
  // Arbitration phase at the nominal rate: SOF, id 11, SRR, IDE, id 18, RRS, FDF, res, BRS.
  const int arbitration = 1 + 11 + 1 + 1 + 18 + 1 + 1 + 1 + 1;
  // Data phase: ESI, DLC 4, data (dynamically stuffed), then stuff count 4 and CRC 17 (payload
  // <= 16 bytes) or 21 with fixed stuff bits (one before the stuff count, one after every 4
  // bits), CRC delimiter.
  const int dynamic = 1 + 4 + data_bits;
  const int crc = payload <= 16 ? 17 : 21;
  const int fixed_stuff = 1 + (4 + crc - 1) / 4;
  // ACK slot and delimiter, EOF 7, interframe space 3 at the nominal rate.
  return {arbitration + stuff(arbitration) + 12, dynamic + (worst_case ? dynamic / 4 : 0) + 4 + crc + fixed_stuff + 1};
}

double MaxSampleRate(const CanFrameLayout& layout, const CanBitrates& rates, double bus_load, int status_every) {
  const double sample_frame = FrameBits(layout.fd, layout.sample_payload(), true).Seconds(rates);
  const double status_frame = FrameBits(false, 8, true).Seconds(rates);
  const double per_set = sample_frame / layout.sets_per_frame() + (status_every > 0 ? status_frame / status_every : 0.0);
  return bus_load / per_set;
}

// ---------------------------------------------------------------------------------------------
// The module's side

CanSampleEncoder::CanSampleEncoder(CanFrameLayout layout) : layout_(layout) {
  std::string error;
  if (!layout_.IsValid(&error)) throw std::invalid_argument("CAN frame layout: " + error);
  pending_.reserve(static_cast<std::size_t>(layout_.sets_per_frame() * layout_.channels));
}

void CanSampleEncoder::Add(std::span<const std::int16_t> set, std::vector<CanFrame>& out) {
  if (set.size() != static_cast<std::size_t>(layout_.channels))
    throw std::invalid_argument(fmt::format("CAN sample encoder: {} counts for {} channels", set.size(), layout_.channels));
  pending_.insert(pending_.end(), set.begin(), set.end());
  ++next_index_;
  const int sets = layout_.sets_per_frame();
  if (pending_.size() < static_cast<std::size_t>(sets * layout_.channels)) return;
  CanFrame f;
  f.fd = layout_.fd;
  f.raw.can_id = layout_.sample_id(next_index_ - static_cast<std::uint64_t>(sets));
  f.raw.len = static_cast<std::uint8_t>(layout_.sample_payload());
  if (f.fd) f.raw.flags = CANFD_BRS;
  for (std::size_t i = 0; i < pending_.size(); ++i) PutLe16(f.raw.data + 2 * i, static_cast<std::uint16_t>(pending_[i]));
  out.push_back(f);
  pending_.clear();
}

void CanSampleEncoder::AddStatus(std::uint16_t status_word, std::uint8_t tx_errors, std::uint8_t rx_errors,
                                 std::vector<CanFrame>& out) const {
  CanFrame f;
  f.raw.can_id = layout_.status_id();
  f.raw.len = 8;
  // The next set to go out in a frame: sets still waiting for a full FD frame are not sent yet.
  const std::uint64_t framed = next_index_ - pending_.size() / static_cast<std::size_t>(layout_.channels);
  PutLe32(f.raw.data, static_cast<std::uint32_t>(framed));
  PutLe16(f.raw.data + 4, status_word);
  f.raw.data[6] = tx_errors;
  f.raw.data[7] = rx_errors;
  out.push_back(f);
}

void CanSampleEncoder::Skip(std::uint64_t sets) {
  if (!pending_.empty()) throw std::invalid_argument("CAN sample encoder: Skip inside a partly filled frame");
  next_index_ += sets;
}

CanAcquisitionSender::CanAcquisitionSender(std::unique_ptr<CanTransport> transport, CanFrameLayout layout, int status_every)
    : transport_(std::move(transport)), encoder_(layout), status_every_(status_every) {}

void CanAcquisitionSender::Add(std::span<const std::int16_t> set) {
  encoder_.Add(set, queue_);
  ++queued_sets_;
  if (status_every_ > 0 && encoder_.next_index() % static_cast<std::uint64_t>(status_every_) == 0)
    encoder_.AddStatus(status_, tx_errors_, rx_errors_, queue_);
  if (queued_sets_ >= flush_sets) Flush();
}

void CanAcquisitionSender::Flush() {
  if (!queue_.empty()) transport_->Send(queue_, send_timeout);
  queue_.clear();
  queued_sets_ = 0;
}

void CanAcquisitionSender::SendStatus() {
  encoder_.AddStatus(status_, tx_errors_, rx_errors_, queue_);
  Flush();
}

// ---------------------------------------------------------------------------------------------
// strut's side: the decoder

bool CanAcquisitionOptions::IsValid(std::string* error) const {
  std::string why;
  if (!layout.IsValid(&why)) {
    // why says it
  } else if (!(sample_rate > 0.0) || !std::isfinite(sample_rate)) {
    why = fmt::format("sample rate {} Hz is not positive", sample_rate);
  } else if (channels.size() != static_cast<std::size_t>(layout.channels)) {
    why = fmt::format("{} channel descriptors for a layout of {} channels", channels.size(), layout.channels);
  } else if (stale_after.count() <= 0) {
    why = "stale_after must be positive";
  } else {
    for (const ChannelDescriptor& c : channels) {
      std::string cal;
      if (c.name.empty()) {
        why = "a channel without a name";
        break;
      }
      if (!c.calibration.IsValid(&cal)) {
        why = fmt::format("channel '{}': calibration: {}", c.name, cal);
        break;
      }
    }
  }
  if (why.empty()) return true;
  if (error) *error = why;
  return false;
}

CanStreamDecoder::CanStreamDecoder(CanAcquisitionOptions options) : options_(std::move(options)) {
  std::string error;
  if (!options_.IsValid(&error)) throw std::invalid_argument("CAN acquisition: " + error);
  sets_per_frame_ = options_.layout.sets_per_frame();
  period_ns_ = 1e9 / options_.sample_rate;
  Reset(0);
}

void CanStreamDecoder::Reset(std::int64_t now_ns) {
  stats_ = {};
  started_ = false;
  next_index_ = 0;
  pending_lost_ = 0;
  seq_offset_ = 0;
  consecutive_out_of_step_ = 0;
  anchor_ns_ = 0;
  last_frame_ns_ = now_ns;
  stale_ = false;
  have_device_base_ = false;
  device_base_ = 0;
  bus_off_ = error_passive_ = false;
  device_status_ = 0;
  have_device_status_ = false;
  block_corrupt_ = block_bus_errors_ = 0;
  block_corrupt_what_.clear();
}

std::uint32_t CanStreamDecoder::state_flags() const {
  std::uint32_t f = 0;
  if (bus_off_) f |= Quality::kBusOff;
  if (error_passive_) f |= Quality::kErrorPassive;
  if (device_status_ & can_status::kFaultMask) f |= Quality::kDeviceFault;
  return f;
}

void CanStreamDecoder::Event(AcquiredBlock& block, AcquisitionEvent::Kind kind, std::int64_t t, std::uint64_t count,
                             std::string text) {
  block.events.push_back({kind, t, next_index_, count, std::move(text)});
}

void CanStreamDecoder::Corrupt(AcquiredBlock& block, std::uint64_t& counter, std::int64_t t, const char* what) {
  ++counter;
  ++stats_.corrupt_frames;
  if (block_corrupt_++ == 0) block_corrupt_ns_ = t;
  if (block_corrupt_what_.find(what) == std::string::npos) {
    if (!block_corrupt_what_.empty()) block_corrupt_what_ += ", ";
    block_corrupt_what_ += what;
  }
  block.quality.flags |= Quality::kCorruptFrames;
}

bool CanStreamDecoder::Feed(const CanFrame& frame, std::int64_t t, AcquiredBlock& block) {
  const canid_t id = frame.raw.can_id;
  if (id & CAN_ERR_FLAG) {
    ++stats_.frames;
    FeedError(frame, t, block);
    return true;
  }
  const std::uint32_t eid = id & CAN_EFF_MASK;
  const bool ours = (id & CAN_EFF_FLAG) && !(id & CAN_RTR_FLAG) && ((eid >> 18) & 0x3F) == options_.layout.module;
  const std::uint32_t kind = eid >> 24;
  if (!ours || (kind != CanFrameLayout::kSampleKind && kind != CanFrameLayout::kStatusKind)) {
    ++stats_.frames;
    Corrupt(block, stats_.unknown_id, t, "unknown id");
    return true;
  }
  if (kind == CanFrameLayout::kSampleKind && !FeedSamples(frame, t, block)) return false;
  ++stats_.frames;
  if (kind == CanFrameLayout::kStatusKind) FeedStatus(frame, t, block);
  return true;
}

void CanStreamDecoder::Alive(std::int64_t t, AcquiredBlock& block) {
  if (stale_) {
    stale_ = false;
    Event(block, AcquisitionEvent::Kind::kResumed, t, 0,
          fmt::format("frames from module {} again after {:.0f} ms", options_.layout.module, (t - last_frame_ns_) * 1e-6));
  }
  last_frame_ns_ = t;
  block.last_frame_ns = t;
}

void CanStreamDecoder::FeedError(const CanFrame& frame, std::int64_t t, AcquiredBlock& block) {
  if (frame.fd || frame.raw.len != CAN_ERR_DLC) {
    Corrupt(block, stats_.wrong_length, t, "error frame of wrong length");
    return;
  }
  ++stats_.error_frames;
  const canid_t classes = frame.raw.can_id & CAN_ERR_MASK;
  const std::uint8_t controller = frame.raw.data[1];
  const bool passive_now = (classes & CAN_ERR_CRTL) && (controller & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE));
  const std::uint8_t tec = frame.raw.data[6], rec = frame.raw.data[7];
  const bool counters = (classes & CAN_ERR_CNT) != 0;
  if ((classes & CAN_ERR_BUSOFF) && !bus_off_) {
    bus_off_ = true;
    Event(block, AcquisitionEvent::Kind::kBusOff, t, 0, "the receiver's CAN controller is bus-off: data invalid");
  }
  if ((classes & CAN_ERR_RESTARTED) && (bus_off_ || error_passive_)) {
    bus_off_ = error_passive_ = false;
    Event(block, AcquisitionEvent::Kind::kBusRecovered, t, 0, "the CAN controller restarted: error-active");
  }
  if ((passive_now || (counters && (tec >= 128 || rec >= 128))) && !error_passive_ && !bus_off_) {
    error_passive_ = true;
    Event(block, AcquisitionEvent::Kind::kErrorPassive, t, 0,
          counters ? fmt::format("the receiver's CAN controller is error-passive (tx errors {}, rx errors {}): data invalid",
                                 tec, rec)
                   : std::string("the receiver's CAN controller is error-passive: data invalid"));
  } else if (error_passive_ && !passive_now &&
             (((classes & CAN_ERR_CRTL) && (controller & CAN_ERR_CRTL_ACTIVE)) || (counters && tec < 128 && rec < 128))) {
    error_passive_ = false;
    Event(block, AcquisitionEvent::Kind::kBusRecovered, t, 0, "the receiver's CAN controller is error-active again");
  }
  // Bus state alone (bus-off, restart, counters, passive/active) is handled above; anything else
  // (protocol errors, lost arbitration, missing ACK, transceiver faults, warnings, overflows) is a
  // bus error: the frames that did arrive passed their CRC, so the data stay valid, and lost
  // frames show as gaps.
  const canid_t state_classes = CAN_ERR_BUSOFF | CAN_ERR_RESTARTED | CAN_ERR_CNT;
  const std::uint8_t state_bits = CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE | CAN_ERR_CRTL_ACTIVE;
  const bool state_only =
      (classes & ~state_classes & ~CAN_ERR_CRTL) == 0 && (!(classes & CAN_ERR_CRTL) || (controller & ~state_bits) == 0);
  if (!state_only || classes == 0) {
    if (block_bus_errors_++ == 0) block_bus_errors_ns_ = t;
    block.quality.flags |= Quality::kBusErrors;
  }
}

double CanStreamDecoder::ClockSets(std::int64_t t, std::uint64_t base) const {
  const double expected_ns = static_cast<double>(anchor_ns_) + (static_cast<double>(base) + sets_per_frame_ - 1) * period_ns_;
  return (static_cast<double>(t) - expected_ns) / period_ns_;
}

double CanStreamDecoder::ClockTolerance(std::int64_t t) const {
  // Half a second of latency and jitter, plus 200 ppm of the time since the anchor for the
  // module's crystal against the host's clock.
  return std::max(1024.0, 0.5 * options_.sample_rate) + 2e-4 * (static_cast<double>(t - anchor_ns_) / period_ns_);
}

void CanStreamDecoder::FeedStatus(const CanFrame& frame, std::int64_t t, AcquiredBlock& block) {
  if (frame.fd || frame.raw.len != 8) {
    Corrupt(block, stats_.wrong_length, t, "status frame of wrong length");
    return;
  }
  const std::uint32_t index = Le32(frame.raw.data);
  const std::uint16_t word = Le16(frame.raw.data + 4);
  if (started_) {
    // The full 32-bit index catches losses the 18-bit sequence cannot see (whole multiples of
    // 2^18 sets) when the clock agrees; the remainder shows in the next sample frame's sequence.
    const std::uint64_t base = next_index_ + pending_lost_;
    if (!have_device_base_) {
      device_base_ = index - static_cast<std::uint32_t>(base);
      have_device_base_ = true;
    } else {
      const std::uint32_t ahead = index - (device_base_ + static_cast<std::uint32_t>(base));
      const std::uint64_t aliased = ahead < (1u << 31) ? ahead & ~CanFrameLayout::kSequenceMask : 0;
      if (aliased > 0 && static_cast<double>(aliased) > ClockSets(t, base) + ClockTolerance(t)) {
        Corrupt(block, stats_.ahead_of_clock, t, "status frame index ahead of the clock");
        return;
      }
      pending_lost_ += aliased;
    }
  }
  Alive(t, block);
  ++stats_.status_frames;
  if (!have_device_status_ || word != device_status_) {
    Event(block, AcquisitionEvent::Kind::kDeviceStatus, t, word,
          fmt::format("module {} status {}, tx errors {}, rx errors {}", options_.layout.module, StatusText(word),
                      frame.raw.data[6], frame.raw.data[7]));
    device_status_ = word;
    have_device_status_ = true;
  }
}

bool CanStreamDecoder::FeedSamples(const CanFrame& frame, std::int64_t t, AcquiredBlock& block) {
  const CanFrameLayout& layout = options_.layout;
  if (frame.fd != layout.fd || frame.raw.len != layout.sample_payload()) {
    Corrupt(block, stats_.wrong_length, t, "sample frame of wrong length");
    return true;
  }
  const std::uint32_t seq = frame.raw.can_id & CanFrameLayout::kSequenceMask;
  constexpr std::uint64_t kWrap = 1ull << CanFrameLayout::kSequenceBits;
  std::uint64_t lost = 0;
  bool resync = false;
  if (started_) {
    const std::uint64_t base = next_index_ + pending_lost_;
    const std::uint64_t diff = (seq - (base + seq_offset_)) & CanFrameLayout::kSequenceMask;
    // How many sets the clock says went by: decides whole wraps of the sequence after a silence,
    // and refuses a sequence that runs ahead of time (a corrupted id, not a gap).
    const double by_clock = ClockSets(t, base);
    const bool late = by_clock <= kWrap / 4.0 && diff >= kWrap / 2;
    if (by_clock > kWrap / 4.0) {
      const double wraps = std::max(0.0, std::round((by_clock - static_cast<double>(diff)) / kWrap));
      lost = pending_lost_ + diff + static_cast<std::uint64_t>(wraps) * kWrap;
    } else if (!late) {
      lost = pending_lost_ + diff;
    }
    const bool ahead = !late && static_cast<double>(lost - pending_lost_) > by_clock + ClockTolerance(t);
    if (late || ahead) {
      // A repeated or reordered frame, or one from the future: dropped. A run of them means the
      // module's sequence jumped (a restart): follow it rather than drop everything.
      if (consecutive_out_of_step_ + 1 < kResyncAfterFrames) {
        ++consecutive_out_of_step_;
        if (late)
          Corrupt(block, stats_.late_frames, t, "late or repeated sample frame");
        else
          Corrupt(block, stats_.ahead_of_clock, t, "sample frame sequence ahead of the clock");
        return true;
      }
      resync = true;
      lost = 0;
    }
  }
  const std::uint32_t flags = state_flags() | (lost > 0 || resync ? Quality::kSequenceGap : 0u);
  if (!block.empty() &&
      (lost > 0 || resync || (flags & Quality::kInvalidMask) != (block.quality.flags & Quality::kInvalidMask)))
    return false;  // starts a new block

  Alive(t, block);
  consecutive_out_of_step_ = 0;
  if (resync) {
    const std::uint32_t jump = (seq - seq_offset_ - static_cast<std::uint32_t>(next_index_)) & CanFrameLayout::kSequenceMask;
    seq_offset_ = (seq - static_cast<std::uint32_t>(next_index_)) & CanFrameLayout::kSequenceMask;
    pending_lost_ = 0;
    have_device_base_ = false;
    // Time restarts from this frame's arrival, never before the sets already delivered.
    anchor_ns_ = std::max(anchor_ns_, t - static_cast<std::int64_t>((static_cast<double>(next_index_) + sets_per_frame_ - 1) * period_ns_));
    ++stats_.resyncs;
    Event(block, AcquisitionEvent::Kind::kResynchronised, t, jump,
          fmt::format("module {}'s sequence jumped by {} sets mod 2^18, against the clock (a restart?); {} frames "
                      "dropped before following it",
                      options_.layout.module, jump, kResyncAfterFrames - 1));
  }
  if (!started_) {
    started_ = true;
    seq_offset_ = seq;  // our set 0 is the module's set `seq` (mod 2^18)
    anchor_ns_ = t - static_cast<std::int64_t>((sets_per_frame_ - 1) * period_ns_);
  }
  const std::uint64_t index = next_index_ + lost;
  if (lost > 0) {
    ++stats_.gaps;
    stats_.lost_sample_sets += lost;
    Event(block, AcquisitionEvent::Kind::kSequenceGap, t, lost,
          fmt::format("{} sample sets lost (indices {} to {})", lost, next_index_, index - 1));
  }
  pending_lost_ = 0;
  const int channels = layout.channels;
  if (block.empty()) {
    block.first_index = index;
    block.lost_before = lost;
    block.quality.flags |= flags;
    block.counts.resize(static_cast<std::size_t>(channels));
    block.values.resize(static_cast<std::size_t>(channels));
  }
  for (int s = 0; s < sets_per_frame_; ++s) {
    block.time_ns.push_back(anchor_ns_ + static_cast<std::int64_t>(std::llround(static_cast<double>(index + s) * period_ns_)));
    for (int c = 0; c < channels; ++c) {
      const auto counts = static_cast<std::int16_t>(Le16(frame.raw.data + 2 * (s * channels + c)));
      const Calibration& cal = options_.channels[static_cast<std::size_t>(c)].calibration;
      const double value = cal.ToSi(counts);
      block.counts[c].push_back(counts);
      block.values[c].push_back(value);
      if (counts == INT16_MIN || counts == INT16_MAX || !cal.InRange(value)) block.quality.flags |= Quality::kOverRange;
    }
  }
  next_index_ = index + static_cast<std::uint64_t>(sets_per_frame_);
  stats_.sample_sets += static_cast<std::uint64_t>(sets_per_frame_);
  if (flags & Quality::kInvalidMask) stats_.invalid_sample_sets += static_cast<std::uint64_t>(sets_per_frame_);
  return true;
}

void CanStreamDecoder::CheckStale(std::int64_t now_ns, AcquiredBlock& block) {
  if (!stale_ && now_ns - last_frame_ns_ > options_.stale_after.count()) {
    stale_ = true;
    ++stats_.stale_periods;
    Event(block, AcquisitionEvent::Kind::kStale, now_ns, 0,
          fmt::format("no frame from module {} for {:.0f} ms (stale after {} ms): the stream is frozen",
                      options_.layout.module, (now_ns - last_frame_ns_) * 1e-6,
                      std::chrono::duration_cast<std::chrono::milliseconds>(options_.stale_after).count()));
  }
  if (stale_) block.quality.flags |= Quality::kStale;
}

void CanStreamDecoder::AddMalformed(std::uint64_t count, std::int64_t now_ns, AcquiredBlock& block) {
  for (std::uint64_t i = 0; i < count; ++i) Corrupt(block, stats_.malformed_datagrams, now_ns, "not a CAN frame");
}

void CanStreamDecoder::AddReceiverDrops(std::uint64_t count, std::int64_t now_ns, AcquiredBlock& block) {
  stats_.receiver_drops += count;
  Event(block, AcquisitionEvent::Kind::kReceiverDrops, now_ns, count,
        fmt::format("the receiving socket dropped {} frames (queue full): the samples show as a gap", count));
}

void CanStreamDecoder::Finish(AcquiredBlock& block) {
  if (block_corrupt_ > 0)
    Event(block, AcquisitionEvent::Kind::kCorruptFrames, block_corrupt_ns_, block_corrupt_,
          fmt::format("{} corrupted frames dropped ({})", block_corrupt_, block_corrupt_what_));
  if (block_bus_errors_ > 0)
    Event(block, AcquisitionEvent::Kind::kBusErrors, block_bus_errors_ns_, block_bus_errors_,
          fmt::format("{} CAN error frames (bus errors, warnings or overflows)", block_bus_errors_));
  block_corrupt_ = block_bus_errors_ = 0;
  block_corrupt_what_.clear();
}

// ---------------------------------------------------------------------------------------------
// strut's side: the module

CanAcquisition::CanAcquisition(std::unique_ptr<CanTransport> transport, CanAcquisitionOptions options)
    : transport_(std::move(transport)), decoder_(std::move(options)) {
  const CanAcquisitionOptions& o = decoder_.options();
  description_.source = fmt::format("{} module {}", transport_->name(), o.layout.module);
  description_.sample_rate = o.sample_rate;
  description_.channels = o.channels;
  block_sets_ = o.block_sets > 0 ? o.block_sets : std::max<std::size_t>(1, static_cast<std::size_t>(o.sample_rate / 100));
  batch_.resize(64);
}

void CanAcquisition::Start() {
  transport_->Flush();
  seen_ = transport_->counters();
  batch_pos_ = batch_size_ = 0;
  decoder_.Reset(MonotonicNs());
  running_ = true;
}

void CanAcquisition::Stop() { running_ = false; }

AcquiredBlock CanAcquisition::Read(std::chrono::nanoseconds timeout) {
  if (!running_)
    throw DeviceError(DeviceError::Kind::kInvalidValue, description_.source, "read", "", 0,
                      "Read before Start or after Stop");
  const std::int64_t deadline = MonotonicNs() + timeout.count();
  AcquiredBlock block;
  const auto finish = [&] {
    decoder_.Finish(block);
    block.clock = NowTimePair();
    return std::move(block);
  };
  for (;;) {
    while (batch_pos_ < batch_size_) {
      if (!decoder_.Feed(batch_[batch_pos_], batch_time_ns_, block)) return finish();
      ++batch_pos_;
      if (block.size() >= block_sets_) return finish();
    }
    const std::int64_t now = MonotonicNs();
    if (now >= deadline) break;
    batch_size_ = transport_->Receive(batch_, std::chrono::nanoseconds(deadline - now));
    batch_pos_ = 0;
    batch_time_ns_ = MonotonicNs();
    const CanTransportCounters c = transport_->counters();
    if (c.malformed > seen_.malformed) decoder_.AddMalformed(c.malformed - seen_.malformed, batch_time_ns_, block);
    if (c.dropped > seen_.dropped) decoder_.AddReceiverDrops(c.dropped - seen_.dropped, batch_time_ns_, block);
    seen_ = c;
  }
  decoder_.CheckStale(MonotonicNs(), block);
  return finish();
}

}  // namespace strut::daq
