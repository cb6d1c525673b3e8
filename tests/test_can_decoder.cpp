// The CAN stream decoder without I/O: samples and their calibration, sequence gaps (also hidden
// ones that only the status frame's 32-bit index shows), corrupted frames, error frames and the
// bus state, module faults, timestamps, and the stale check.
#include <gtest/gtest.h>

#include <numeric>

#include "can_test_support.h"
#include "strut/daq/can_acquisition.h"

namespace strut::daq {
namespace {

using test::ErrorFrame;
using test::FourChannelOptions;
using test::Ramp;

constexpr std::int64_t kT0 = 1'000'000'000;  // ns

//! A decoder for `options` whose stream starts at kT0.
CanStreamDecoder StartedDecoder(const CanAcquisitionOptions& options) {
  CanStreamDecoder decoder(options);
  decoder.Reset(kT0);
  return decoder;
}

//! `more` after the frames so far.
void Append(std::vector<CanFrame>& frames, const std::vector<CanFrame>& more) {
  frames.insert(frames.end(), more.begin(), more.end());
}

//! Feeds frames as a Read loop would (a new block when Feed refuses a frame), all received at
//! `t` (or one period apart when `spaced`); returns the finished blocks, non-empty ones and the last.
struct Fed {
  std::vector<AcquiredBlock> blocks;
  const AcquiredBlock& last() const { return blocks.back(); }
  std::size_t sets() const {
    std::size_t n = 0;
    for (const auto& b : blocks) n += b.size();
    return n;
  }
  std::vector<AcquisitionEvent> events() const {
    std::vector<AcquisitionEvent> all;
    for (const auto& b : blocks) all.insert(all.end(), b.events.begin(), b.events.end());
    return all;
  }
  bool has_event(AcquisitionEvent::Kind kind) const {
    for (const auto& e : events())
      if (e.kind == kind) return true;
    return false;
  }
};

Fed FeedAll(CanStreamDecoder& decoder, const std::vector<CanFrame>& frames, std::int64_t t = kT0,
            const std::vector<std::int64_t>& times = {}) {
  Fed fed;
  AcquiredBlock block;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const CanFrame& f = frames[i];
    if (!times.empty()) t = times[i];
    if (!decoder.Feed(f, t, block)) {
      decoder.Finish(block);
      fed.blocks.push_back(std::move(block));
      block = {};
      EXPECT_TRUE(decoder.Feed(f, t, block)) << "a fresh block must take the frame";
    }
  }
  decoder.Finish(block);
  fed.blocks.push_back(std::move(block));
  return fed;
}

TEST(CanStreamDecoder, DecodesCountsAndAppliesEachChannelsCalibration) {
  const auto options = FourChannelOptions();
  CanSampleEncoder encoder(options.layout);
  std::vector<CanFrame> frames;
  // Hand-computed counts: 0.12345 m -> 12345; 5000 N -> (5000 + 1000) / 2 = 3000;
  // 300.15 K -> (300.15 - 273.15) / 0.01 = 2700; pressure count 0 -> the middle of 20 MPa.
  const std::int16_t set[] = {12345, 3000, 0, 2700};
  encoder.Add(set, frames);
  CanStreamDecoder decoder = StartedDecoder(options);
  const Fed fed = FeedAll(decoder, frames);
  ASSERT_EQ(fed.blocks.size(), 1u);
  const AcquiredBlock& b = fed.last();
  ASSERT_EQ(b.size(), 1u);
  EXPECT_EQ(b.counts[0][0], 12345);
  EXPECT_NEAR(b.values[0][0], 0.12345, 1e-12);
  EXPECT_DOUBLE_EQ(b.values[1][0], 5000.0);
  EXPECT_NEAR(b.values[2][0], 10e6, 305.2);
  EXPECT_NEAR(b.values[3][0], 300.15, 1e-9);
  EXPECT_TRUE(b.quality.valid());
  EXPECT_EQ(b.quality.flags, 0u) << b.quality.ToString();
}

TEST(CanStreamDecoder, ContinuousStreamAcrossTheSequenceWrapHasNoGap) {
  auto options = FourChannelOptions(true, 50000.0);
  CanSampleEncoder encoder(options.layout);
  encoder.Skip((1u << 18) - 800);  // the module has been running; the sequence wraps inside the run
  std::vector<CanFrame> frames;
  for (int i = 0; i < 2000; ++i) {
    const std::int16_t set[] = {static_cast<std::int16_t>(i), 0, 0, 0};
    encoder.Add(set, frames);
  }
  CanStreamDecoder decoder = StartedDecoder(options);
  AcquiredBlock block;
  for (std::size_t i = 0; i < frames.size(); ++i)
    ASSERT_TRUE(decoder.Feed(frames[i], kT0 + static_cast<std::int64_t>(i * 160'000), block));  // 8 sets at 50 kHz
  ASSERT_EQ(block.size(), 2000u);
  EXPECT_EQ(decoder.stats().lost_sample_sets, 0u);
  EXPECT_EQ(block.first_index, 0u);
  for (int i = 0; i < 2000; ++i) ASSERT_EQ(block.counts[0][i], i);
  // The linear time rule: one period (20 µs) apart, set 7 of the first frame at its arrival.
  EXPECT_EQ(block.time_ns[7], kT0);
  EXPECT_EQ(block.time_ns[1999] - block.time_ns[0], 1999 * 20'000);
}

TEST(CanStreamDecoder, SequenceGapEndsTheBlockAndIsRecordedWithItsSize) {
  const auto options = FourChannelOptions();
  CanSampleEncoder encoder(options.layout);
  auto frames = Ramp(encoder, 0, 10);
  encoder.Skip(25);
  const auto more = Ramp(encoder, 35, 10);
  frames.insert(frames.end(), more.begin(), more.end());
  CanStreamDecoder decoder = StartedDecoder(options);
  const Fed fed = FeedAll(decoder, frames);
  ASSERT_EQ(fed.blocks.size(), 2u);
  EXPECT_EQ(fed.blocks[0].size(), 10u);
  EXPECT_FALSE(fed.blocks[0].quality.has(Quality::kSequenceGap));
  const AcquiredBlock& after = fed.blocks[1];
  EXPECT_EQ(after.first_index, 35u);
  EXPECT_EQ(after.lost_before, 25u);
  EXPECT_TRUE(after.quality.has(Quality::kSequenceGap));
  EXPECT_TRUE(after.quality.valid());  // the samples that did arrive are good
  EXPECT_EQ(after.counts[0][0], 35);
  // Timestamps keep the lost sets' places: 35 periods of 500 µs after set 0.
  EXPECT_EQ(after.time_ns[0] - fed.blocks[0].time_ns[0], 35 * 500'000);
  EXPECT_EQ(decoder.stats().gaps, 1u);
  EXPECT_EQ(decoder.stats().lost_sample_sets, 25u);
  ASSERT_TRUE(fed.has_event(AcquisitionEvent::Kind::kSequenceGap));
  EXPECT_NE(after.events[0].text.find("25 sample sets lost (indices 10 to 34)"), std::string::npos)
      << after.events[0].text;
}

//! Arrival times of frames sent in real time at 2 kHz: frame k (one set each) at set `index[k]`.
std::vector<std::int64_t> ArrivalTimes(const std::vector<std::uint64_t>& indices) {
  std::vector<std::int64_t> t;
  for (const auto i : indices) t.push_back(kT0 + static_cast<std::int64_t>(i) * 500'000);
  return t;
}

TEST(CanStreamDecoder, StatusFrameIndexCountsWholeSequenceWrapsTheClockConfirms) {
  const auto options = FourChannelOptions();
  CanSampleEncoder encoder(options.layout);
  const std::uint64_t skipped = (1u << 18) * 2 + 3;  // invisible to the 18-bit sequence but for 3
  auto frames = Ramp(encoder, 0, 10);
  encoder.AddStatus(0, 0, 0, frames);  // gives the module's 32-bit index of our set 0
  encoder.Skip(skipped);
  encoder.AddStatus(0, 0, 0, frames);
  const auto more = Ramp(encoder, 0, 5);
  frames.insert(frames.end(), more.begin(), more.end());
  std::vector<std::uint64_t> at = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 10 + skipped};
  for (std::uint64_t i = 0; i < 5; ++i) at.push_back(10 + skipped + i);
  CanStreamDecoder decoder = StartedDecoder(options);
  const Fed fed = FeedAll(decoder, frames, kT0, ArrivalTimes(at));
  ASSERT_EQ(fed.blocks.size(), 2u);
  EXPECT_EQ(fed.blocks[1].lost_before, skipped);
  EXPECT_EQ(fed.blocks[1].first_index, 10u + skipped);
  EXPECT_EQ(fed.blocks[1].time_ns[0], kT0 + static_cast<std::int64_t>(10 + skipped) * 500'000);
}

TEST(CanStreamDecoder, SequenceOrIndexAheadOfTheClockIsDroppedNotAGap) {
  const auto options = FourChannelOptions();  // 2 kHz: tolerance 1024 sets (half a second, at least 1024)
  CanSampleEncoder encoder(options.layout);
  auto frames = Ramp(encoder, 0, 10);
  encoder.AddStatus(0, 0, 0, frames);
  CanFrame bogus_status = frames.back();
  bogus_status.raw.data[3] ^= 0x40;  // index + 2^30: a corrupted status frame
  frames.push_back(bogus_status);
  CanFrame bogus_sample = Ramp(encoder, 10, 1)[0];
  bogus_sample.raw.can_id ^= 1u << 16;  // sequence + 65536 sets, 33 s ahead of a clock that says 5 ms
  frames.push_back(bogus_sample);
  Append(frames, Ramp(encoder, 11, 5));
  std::vector<std::int64_t> times;
  for (int i = 0; i < 10; ++i) times.push_back(kT0 + i * 500'000);
  for (int i = 0; i < 8; ++i) times.push_back(kT0 + (10 + i) * 500'000);
  CanStreamDecoder decoder = StartedDecoder(options);
  const Fed fed = FeedAll(decoder, frames, kT0, times);
  EXPECT_EQ(decoder.stats().ahead_of_clock, 2u);
  EXPECT_EQ(decoder.stats().lost_sample_sets, 1u);  // only the set the bogus frame carried
  EXPECT_EQ(fed.last().first_index, 11u);
  EXPECT_EQ(fed.last().counts[0].front(), 11);
}

TEST(CanStreamDecoder, ModuleRestartIsFollowedAfterARunOfOutOfStepFrames) {
  const auto options = FourChannelOptions();
  CanSampleEncoder before(options.layout);
  before.Skip(100000);
  auto frames = Ramp(before, 0, 20);
  CanSampleEncoder restarted(options.layout);  // counts from 0 again: behind the stream
  Append(frames, Ramp(restarted, 1000, 40));
  std::vector<std::int64_t> times;
  for (std::size_t i = 0; i < frames.size(); ++i) times.push_back(kT0 + static_cast<std::int64_t>(i) * 500'000);
  CanStreamDecoder decoder = StartedDecoder(options);
  const Fed fed = FeedAll(decoder, frames, kT0, times);
  EXPECT_EQ(decoder.stats().late_frames, 15u);
  EXPECT_EQ(decoder.stats().resyncs, 1u);
  ASSERT_EQ(fed.blocks.size(), 2u);
  const AcquiredBlock& after = fed.blocks[1];
  EXPECT_TRUE(after.quality.has(Quality::kSequenceGap));
  EXPECT_EQ(after.first_index, 20u);  // indices continue
  EXPECT_EQ(after.counts[0].front(), 1015);  // the 16th frame after the restart is the first kept
  EXPECT_EQ(after.size(), 25u);
  EXPECT_GT(after.time_ns.front(), fed.blocks[0].time_ns.back());
  EXPECT_EQ(after.events.front().kind, AcquisitionEvent::Kind::kResynchronised);
}

TEST(CanStreamDecoder, LongSilenceIsMeasuredByTheClockBeyondTheSequenceRange) {
  const auto options = FourChannelOptions(false, 2000.0);
  CanSampleEncoder encoder(options.layout);
  const auto first = Ramp(encoder, 0, 4);
  const std::uint64_t lost = (1u << 18) + 1000;  // 131.5 s at 2 kHz
  encoder.Skip(lost);
  const auto second = Ramp(encoder, 0, 4);
  CanStreamDecoder decoder = StartedDecoder(options);
  AcquiredBlock a, b;
  for (int i = 0; i < 4; ++i) ASSERT_TRUE(decoder.Feed(first[i], kT0 + i * 500'000, a));
  const std::int64_t later = kT0 + static_cast<std::int64_t>((4 + lost) * 500'000);
  EXPECT_FALSE(decoder.Feed(second[0], later, a));
  EXPECT_TRUE(decoder.Feed(second[0], later, b));
  EXPECT_EQ(b.lost_before, lost);
}

TEST(CanStreamDecoder, CorruptedFramesAreDroppedAndCountedByKind) {
  const auto options = FourChannelOptions();
  CanSampleEncoder encoder(options.layout);
  auto frames = Ramp(encoder, 0, 6);
  CanFrame short_frame = frames[2];
  short_frame.raw.len = 6;  // wrong DLC
  CanFrame foreign = frames[3];
  foreign.raw.can_id = CAN_EFF_FLAG | (0x08u << 24) | (6u << 18);  // module 6, not 5
  CanFrame standard = frames[3];
  standard.raw.can_id = 0x123;  // standard id
  CanFrame remote = frames[3];
  remote.raw.can_id |= CAN_RTR_FLAG;
  CanFrame fd = frames[3];
  fd.fd = true;  // right length, wrong frame format
  CanFrame status = frames[3];
  status.raw.can_id = CAN_EFF_FLAG | (0x04u << 24) | (5u << 18);
  status.raw.len = 4;
  frames[2] = short_frame;  // replaces set 2: it is lost
  frames.insert(frames.begin() + 4, {foreign, standard, remote, fd, status});
  CanStreamDecoder decoder = StartedDecoder(options);
  const Fed fed = FeedAll(decoder, frames);
  const AcquisitionStats& s = decoder.stats();
  EXPECT_EQ(s.wrong_length, 3u);  // short sample frame, FD sample frame, short status frame
  EXPECT_EQ(s.unknown_id, 3u);
  EXPECT_EQ(s.corrupt_frames, 6u);
  EXPECT_EQ(s.lost_sample_sets, 1u);  // the frame with the wrong DLC carried set 2
  EXPECT_EQ(fed.sets(), 5u);
  std::string texts;
  std::uint64_t counted = 0;
  for (const auto& e : fed.events())
    if (e.kind == AcquisitionEvent::Kind::kCorruptFrames) {
      texts += e.text + "\n";
      counted += e.count;
    }
  EXPECT_EQ(counted, 6u);  // every dropped frame is in an event
  EXPECT_NE(texts.find("sample frame of wrong length"), std::string::npos) << texts;
  EXPECT_NE(texts.find("status frame of wrong length"), std::string::npos) << texts;
  EXPECT_NE(texts.find("unknown id"), std::string::npos) << texts;
  EXPECT_TRUE(fed.blocks[0].quality.has(Quality::kCorruptFrames));
}

TEST(CanStreamDecoder, RepeatedFrameIsDroppedAsLate) {
  const auto options = FourChannelOptions();
  CanSampleEncoder encoder(options.layout);
  auto frames = Ramp(encoder, 0, 5);
  frames.insert(frames.begin() + 3, frames[1]);
  CanStreamDecoder decoder = StartedDecoder(options);
  const Fed fed = FeedAll(decoder, frames);
  EXPECT_EQ(decoder.stats().late_frames, 1u);
  EXPECT_EQ(decoder.stats().lost_sample_sets, 0u);
  ASSERT_EQ(fed.blocks.size(), 1u);
  EXPECT_EQ(fed.last().counts[0], (std::vector<std::int32_t>{0, 1, 2, 3, 4}));
}

TEST(CanStreamDecoder, BusOffMarksTheDataInvalidUntilTheControllerRestarts) {
  const auto options = FourChannelOptions();
  CanSampleEncoder encoder(options.layout);
  std::vector<CanFrame> frames = Ramp(encoder, 0, 3);
  frames.push_back(ErrorFrame(CAN_ERR_BUSOFF));
  Append(frames, Ramp(encoder, 3, 3));
  frames.push_back(ErrorFrame(CAN_ERR_RESTARTED));
  Append(frames, Ramp(encoder, 6, 3));
  CanStreamDecoder decoder = StartedDecoder(options);
  const Fed fed = FeedAll(decoder, frames);
  ASSERT_EQ(fed.blocks.size(), 3u);
  EXPECT_TRUE(fed.blocks[0].quality.valid());
  EXPECT_FALSE(fed.blocks[1].quality.valid());
  EXPECT_TRUE(fed.blocks[1].quality.has(Quality::kBusOff));
  EXPECT_EQ(fed.blocks[1].first_index, 3u);
  EXPECT_EQ(fed.blocks[1].size(), 3u);  // delivered, not dropped: only marked
  EXPECT_TRUE(fed.blocks[2].quality.valid());
  EXPECT_EQ(decoder.stats().invalid_sample_sets, 3u);
  EXPECT_TRUE(fed.has_event(AcquisitionEvent::Kind::kBusOff));
  EXPECT_TRUE(fed.has_event(AcquisitionEvent::Kind::kBusRecovered));
}

TEST(CanStreamDecoder, ErrorPassiveFromControllerOrCountersAndBackToActive) {
  const auto options = FourChannelOptions();
  CanSampleEncoder encoder(options.layout);
  std::vector<CanFrame> frames = Ramp(encoder, 0, 2);
  frames.push_back(ErrorFrame(CAN_ERR_CRTL | CAN_ERR_CNT, CAN_ERR_CRTL_RX_PASSIVE, 3, 128));
  Append(frames, Ramp(encoder, 2, 2));
  frames.push_back(ErrorFrame(CAN_ERR_PROT));  // a protocol error: data stay valid (and invalid stays)
  Append(frames, Ramp(encoder, 4, 2));
  frames.push_back(ErrorFrame(CAN_ERR_CNT, 0, 3, 90));  // counters below 128: error-active again
  Append(frames, Ramp(encoder, 6, 2));
  CanStreamDecoder decoder = StartedDecoder(options);
  const Fed fed = FeedAll(decoder, frames);
  ASSERT_EQ(fed.blocks.size(), 3u);
  EXPECT_TRUE(fed.blocks[0].quality.valid());
  EXPECT_TRUE(fed.blocks[1].quality.has(Quality::kErrorPassive));
  EXPECT_TRUE(fed.blocks[1].quality.has(Quality::kBusErrors));
  EXPECT_EQ(fed.blocks[1].size(), 4u);
  EXPECT_TRUE(fed.blocks[2].quality.valid());
  EXPECT_EQ(decoder.stats().error_frames, 3u);
  for (const auto& e : fed.events())
    if (e.kind == AcquisitionEvent::Kind::kErrorPassive) {
      EXPECT_NE(e.text.find("rx errors 128"), std::string::npos);
    }
}

TEST(CanStreamDecoder, WarningsAndProtocolErrorsAreFlaggedButLeaveTheDataValid) {
  const auto options = FourChannelOptions();
  CanSampleEncoder encoder(options.layout);
  std::vector<CanFrame> frames = Ramp(encoder, 0, 2);
  frames.push_back(ErrorFrame(CAN_ERR_CRTL, CAN_ERR_CRTL_RX_WARNING));
  frames.push_back(ErrorFrame(CAN_ERR_PROT | CAN_ERR_BUSERROR));
  frames.push_back(ErrorFrame(CAN_ERR_CRTL, CAN_ERR_CRTL_RX_OVERFLOW));
  Append(frames, Ramp(encoder, 2, 2));
  CanStreamDecoder decoder = StartedDecoder(options);
  const Fed fed = FeedAll(decoder, frames);
  ASSERT_EQ(fed.blocks.size(), 1u);
  EXPECT_TRUE(fed.last().quality.valid());
  EXPECT_TRUE(fed.last().quality.has(Quality::kBusErrors));
  EXPECT_EQ(fed.last().size(), 4u);
  ASSERT_EQ(fed.last().events.size(), 1u);
  EXPECT_EQ(fed.last().events[0].kind, AcquisitionEvent::Kind::kBusErrors);
  EXPECT_EQ(fed.last().events[0].count, 3u);
}

TEST(CanStreamDecoder, ModuleFaultInTheStatusWordMarksTheDataInvalid) {
  const auto options = FourChannelOptions();
  CanSampleEncoder encoder(options.layout);
  std::vector<CanFrame> frames;
  encoder.AddStatus(can_status::kSimulated, 0, 0, frames);
  Append(frames, Ramp(encoder, 0, 2));
  encoder.AddStatus(can_status::kSimulated | can_status::kExcitationFault, 0, 0, frames);
  Append(frames, Ramp(encoder, 2, 2));
  encoder.AddStatus(can_status::kSimulated | can_status::kBufferOverflow, 0, 0, frames);  // not a fault
  Append(frames, Ramp(encoder, 4, 2));
  CanStreamDecoder decoder = StartedDecoder(options);
  const Fed fed = FeedAll(decoder, frames);
  ASSERT_EQ(fed.blocks.size(), 3u);
  EXPECT_TRUE(fed.blocks[0].quality.valid());
  EXPECT_TRUE(fed.blocks[1].quality.has(Quality::kDeviceFault));
  EXPECT_TRUE(fed.blocks[2].quality.valid());
  int status_events = 0;
  for (const auto& e : fed.events())
    if (e.kind == AcquisitionEvent::Kind::kDeviceStatus) {
      ++status_events;
      if (e.count & can_status::kExcitationFault) {
        EXPECT_NE(e.text.find("excitation fault"), std::string::npos);
      }
    }
  EXPECT_EQ(status_events, 3);
}

TEST(CanStreamDecoder, OverRangeReadingsAreFlagged) {
  const auto options = FourChannelOptions();
  CanSampleEncoder encoder(options.layout);
  std::vector<CanFrame> frames;
  const std::int16_t inside[] = {100, 0, 0, 0};
  const std::int16_t rail[] = {100, 0, 32767, 0};       // pressure at the ADC limit
  const std::int16_t outside[] = {25000, 0, 0, 0};      // 0.25 m: outside the stroke's +-0.2 m
  encoder.Add(inside, frames);
  CanStreamDecoder decoder = StartedDecoder(options);
  EXPECT_FALSE(FeedAll(decoder, frames).last().quality.has(Quality::kOverRange));
  for (const auto* set : {rail, outside}) {
    frames.clear();
    encoder.Add(std::span<const std::int16_t>(set, 4), frames);
    const Fed fed = FeedAll(decoder, frames);
    EXPECT_TRUE(fed.last().quality.has(Quality::kOverRange));
    EXPECT_TRUE(fed.last().quality.valid());
  }
}

TEST(CanStreamDecoder, StaleAfterSilenceAndResumedOnTheNextFrame) {
  const auto options = FourChannelOptions();  // stale after 250 ms
  CanSampleEncoder encoder(options.layout);
  CanStreamDecoder decoder = StartedDecoder(options);
  AcquiredBlock block;
  decoder.CheckStale(kT0 + 200'000'000, block);
  EXPECT_FALSE(block.quality.has(Quality::kStale));
  decoder.CheckStale(kT0 + 300'000'000, block);  // nothing since Reset: frozen from the start
  EXPECT_TRUE(block.quality.has(Quality::kStale));
  ASSERT_EQ(block.events.size(), 1u);
  EXPECT_EQ(block.events[0].kind, AcquisitionEvent::Kind::kStale);
  EXPECT_NE(block.events[0].text.find("no frame from module 5"), std::string::npos) << block.events[0].text;
  AcquiredBlock next;
  decoder.CheckStale(kT0 + 400'000'000, next);  // still stale: flagged, one event only
  EXPECT_TRUE(next.quality.has(Quality::kStale));
  EXPECT_TRUE(next.events.empty());
  AcquiredBlock resumed;
  const auto frames = Ramp(encoder, 0, 1);
  ASSERT_TRUE(decoder.Feed(frames[0], kT0 + 500'000'000, resumed));
  decoder.CheckStale(kT0 + 500'000'000, resumed);
  EXPECT_FALSE(resumed.quality.has(Quality::kStale));
  ASSERT_FALSE(resumed.events.empty());
  EXPECT_EQ(resumed.events[0].kind, AcquisitionEvent::Kind::kResumed);
  EXPECT_EQ(decoder.stats().stale_periods, 1u);
}

}  // namespace
}  // namespace strut::daq
