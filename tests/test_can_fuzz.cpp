// The CAN frame decoder survives any bytes: a million random and mutated transport units
// (deterministic seeds) through CanFrame::FromBytes and CanStreamDecoder, with every unit
// accounted for in the counters and every block self-consistent. The libFuzzer target
// (daq/fuzz/can_decoder_fuzz.cpp, scripts/fuzz-can.sh) explores further with coverage guidance.
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cstring>
#include <iostream>
#include <random>

#include "can_test_support.h"
#include "strut/daq/can_acquisition.h"

namespace strut::daq {
namespace {

//! Checks what a finished block promises: equal lengths, increasing timestamps, indices that
//! follow the previous block's end plus the gap.
void CheckBlock(const AcquiredBlock& b, int channels, std::uint64_t& next_index, std::uint64_t& sets) {
  if (b.empty()) return;
  ASSERT_EQ(b.counts.size(), static_cast<std::size_t>(channels));
  ASSERT_EQ(b.values.size(), static_cast<std::size_t>(channels));
  for (int c = 0; c < channels; ++c) {
    ASSERT_EQ(b.counts[c].size(), b.size());
    ASSERT_EQ(b.values[c].size(), b.size());
  }
  for (std::size_t k = 1; k < b.size(); ++k) ASSERT_LT(b.time_ns[k - 1], b.time_ns[k]);
  ASSERT_EQ(b.first_index, next_index + b.lost_before);
  if (b.lost_before > 0) {
    ASSERT_TRUE(b.quality.has(Quality::kSequenceGap));
  }
  next_index = b.first_index + b.size();
  sets += b.size();
}

struct FuzzRun {
  std::uint64_t units = 0, malformed = 0, fed = 0, sets = 0, lost = 0;
};

//! Feeds `count` units from `next_unit` (bytes of one datagram) through the decoder.
template <class NextUnit>
FuzzRun Fuzz(const CanAcquisitionOptions& options, std::uint64_t count, NextUnit next_unit) {
  CanStreamDecoder decoder(options);
  std::int64_t t = 1'000'000'000;
  decoder.Reset(t);
  FuzzRun run;
  AcquiredBlock block;
  std::uint64_t next_index = 0;
  std::vector<std::uint8_t> bytes;
  const auto finish = [&] {
    decoder.Finish(block);
    CheckBlock(block, options.layout.channels, next_index, run.sets);
    run.lost += block.lost_before;
    block = {};
  };
  for (; run.units < count; ++run.units) {
    next_unit(bytes, t);
    const auto frame = CanFrame::FromBytes(bytes);
    if (!frame) {
      ++run.malformed;
      decoder.AddMalformed(1, t, block);
      continue;
    }
    ++run.fed;
    decoder.CheckStale(t, block);  // as Read does after waiting
    if (!decoder.Feed(*frame, t, block)) {
      finish();
      if (!decoder.Feed(*frame, t, block)) {
        ADD_FAILURE() << "a fresh block refused a frame";
        return run;
      }
    }
    if (block.size() >= 4096) finish();

    if (testing::Test::HasFatalFailure()) return run;
  }
  finish();
  const AcquisitionStats& s = decoder.stats();
  EXPECT_EQ(s.malformed_datagrams, run.malformed);
  EXPECT_EQ(s.frames, run.fed);
  EXPECT_EQ(s.sample_sets, run.sets);
  EXPECT_EQ(s.lost_sample_sets, run.lost);
  // Every frame is a good sample, status or error frame, or counted as corrupt.
  const std::uint64_t sample_frames = s.sample_sets / static_cast<std::uint64_t>(options.layout.sets_per_frame());
  EXPECT_EQ(s.frames, sample_frames + s.status_frames + s.error_frames + (s.corrupt_frames - s.malformed_datagrams));
  EXPECT_EQ(s.corrupt_frames - s.malformed_datagrams, s.wrong_length + s.unknown_id + s.late_frames + s.ahead_of_clock);
  std::cout << fmt::format("{} units: {} sample sets, {} lost in {} gaps, {} resyncs, {} status, {} error frames, "
                           "corrupt {} (malformed {}, wrong length {}, unknown id {}, late {}, ahead {}), {} stale periods\n",
                           run.units, s.sample_sets, s.lost_sample_sets, s.gaps, s.resyncs, s.status_frames,
                           s.error_frames, s.corrupt_frames, s.malformed_datagrams, s.wrong_length, s.unknown_id,
                           s.late_frames, s.ahead_of_clock, s.stale_periods);
  return run;
}

//! Valid frames of a running module (samples, status, error frames), then mutated: bits flipped,
//! lengths and ids changed, frames dropped, repeated or cut to other sizes.
struct Mutator {
  std::mt19937_64 rng;
  CanSampleEncoder encoder;
  std::vector<CanFrame> queue;
  std::size_t pos = 0;
  double frame_ns;         //!< time a sample frame's sets take at the module
  std::int64_t owed_ns = 0;  //!< time of sets the module skipped, added to the next arrival
  Mutator(unsigned long seed, const CanAcquisitionOptions& o)
      : rng(seed), encoder(o.layout), frame_ns(1e9 * o.layout.sets_per_frame() / o.sample_rate) {}

  CanFrame NextValid() {
    while (pos >= queue.size()) {
      queue.clear();
      pos = 0;
      const int kind = static_cast<int>(rng() % 100);
      if (kind < 3) {
        queue.push_back(test::ErrorFrame(static_cast<canid_t>(rng() & 0x3FF), static_cast<std::uint8_t>(rng()),
                                         static_cast<std::uint8_t>(rng()), static_cast<std::uint8_t>(rng())));
      } else if (kind < 6) {
        encoder.AddStatus(static_cast<std::uint16_t>(rng()), 0, 0, queue);
      } else {
        if (kind < 8) {  // a burst of loss; mostly the time passes as it would, now and then not
          const std::uint64_t sets = rng() % (rng() % 2 ? 5 : 600000);
          encoder.Skip(sets);
          if (rng() % 4) owed_ns += static_cast<std::int64_t>(frame_ns * static_cast<double>(sets) / encoder.layout().sets_per_frame());
        }
        const std::int16_t set[4] = {static_cast<std::int16_t>(rng()), static_cast<std::int16_t>(rng()),
                                     static_cast<std::int16_t>(rng()), static_cast<std::int16_t>(rng())};
        for (int i = 0; i < encoder.layout().sets_per_frame(); ++i)
          encoder.Add(std::span<const std::int16_t>(set, static_cast<std::size_t>(encoder.layout().channels)), queue);
      }
    }
    return queue[pos++];
  }

  void operator()(std::vector<std::uint8_t>& bytes, std::int64_t& t) {
    t += static_cast<std::int64_t>(frame_ns * static_cast<double>(rng() % 1000) / 500.0) + owed_ns;  // 0 to 2 frame times
    owed_ns = 0;
    if (rng() % 5000 == 0) t += 400'000'000;            // now and then a silence: stale, then resumed
    CanFrame f = NextValid();
    const int m = static_cast<int>(rng() % 16);
    if (m == 0) f.raw.data[rng() % 64] ^= static_cast<std::uint8_t>(1u << (rng() % 8));
    if (m == 1) f.raw.can_id ^= 1u << (rng() % 32);
    if (m == 2) f.raw.len = static_cast<std::uint8_t>(rng());
    if (m == 3) pos = pos > 1 ? pos - 2 : pos;  // repeat earlier frames
    if (m == 4) f.fd = !f.fd;
    bytes.assign(reinterpret_cast<const std::uint8_t*>(&f.raw), reinterpret_cast<const std::uint8_t*>(&f.raw) + f.wire_size());
    if (m == 5) bytes.resize(rng() % 90);  // cut or padded: not a frame
  }
};

TEST(CanDecoderFuzz, MillionMutatedFramesOfAStreamAllAccountedFor) {
  for (const bool fd : {false, true}) {
    const auto options = test::FourChannelOptions(fd, fd ? 50000.0 : 2000.0);
    const FuzzRun run = Fuzz(options, 500'000, Mutator(fd ? 7 : 3, options));
    EXPECT_GT(run.sets, 100'000u) << "the mutations should leave most of the stream intact";
    EXPECT_GT(run.lost, 0u);
    EXPECT_GT(run.malformed, 0u);
  }
}

TEST(CanDecoderFuzz, RandomBytesOfEverySize) {
  std::mt19937_64 rng(11);
  const auto options = test::FourChannelOptions(true);
  const auto random_unit = [&rng](std::vector<std::uint8_t>& bytes, std::int64_t& t) {
    t += static_cast<std::int64_t>(rng() % 1'000'000);
    const int choice = static_cast<int>(rng() % 4);
    bytes.resize(choice == 0 ? CAN_MTU : choice == 1 ? CANFD_MTU : rng() % 100);
    for (auto& b : bytes) b = static_cast<std::uint8_t>(rng());
    if (bytes.size() > 4 && rng() % 2) {
      // Ids of this module now and then, so the random payloads reach the sample decoder.
      const std::uint32_t id = CAN_EFF_FLAG | ((rng() % 2 ? 0x08u : 0x04u) << 24) | (5u << 18) | (rng() & 0x3FFFF);
      std::memcpy(bytes.data(), &id, 4);
      bytes[4] = bytes.size() == CANFD_MTU ? 64 : 8;
    }
  };
  const FuzzRun run = Fuzz(options, 500'000, random_unit);
  EXPECT_GT(run.malformed, 100'000u);
  EXPECT_GT(run.sets, 0u);
}

}  // namespace
}  // namespace strut::daq
