// The CAN frame layout: calibration, the bytes of sample and status frames (checked against
// hand-written bytes), the bit arithmetic of docs/can-acquisition.md, and frame validation.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstring>

#include "can_test_support.h"
#include "strut/daq/can_acquisition.h"

namespace strut::daq {
namespace {

TEST(Calibration, FromRange16MapsTheWholeSpanOntoTheRange) {
  const Calibration c = Calibration::FromRange16(0.0, 20e6);
  EXPECT_NEAR(c.ToSi(-32768), 0.0, 1e-6);
  EXPECT_NEAR(c.ToSi(32767), 20e6, 1e-6);
  EXPECT_NEAR(c.ToSi(0), 10e6, c.gain);  // the middle of [0, 20 MPa] is count 0 (to a count)
  EXPECT_EQ(c.ToCounts16(-1.0), -32768);
  EXPECT_EQ(c.ToCounts16(1e9), 32767);  // saturates
}

TEST(Calibration, CountsRoundTripAndHandComputedValues) {
  const auto o = test::FourChannelOptions();
  const Calibration& stroke = o.channels[0].calibration;
  const Calibration& force = o.channels[1].calibration;
  EXPECT_EQ(stroke.ToCounts16(0.12345), 12345);   // 0.12345 m / 10 µm
  EXPECT_EQ(stroke.ToCounts16(-0.0500049), -5000);  // rounds to the nearest count
  EXPECT_EQ(force.ToCounts16(5000.0), 3000);       // (5000 + 1000) / 2
  EXPECT_DOUBLE_EQ(force.ToSi(-500), -2000.0);
  for (int counts = -32768; counts <= 32767; counts += 7) EXPECT_EQ(force.ToCounts16(force.ToSi(counts)), counts);
}

TEST(Calibration, InvalidOnesAreRefusedWithTheReason) {
  std::string error;
  Calibration c;
  c.gain = 0.0;
  EXPECT_FALSE(c.IsValid(&error));
  EXPECT_NE(error.find("gain"), std::string::npos);
  c = Calibration::FromRange16(0.0, 1.0);
  c.range_max = 0.0;
  EXPECT_FALSE(c.IsValid(&error));
  EXPECT_NE(error.find("range"), std::string::npos);
  auto o = test::FourChannelOptions();
  o.channels[2].calibration.offset = NAN;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_NE(error.find("channel 'pressure'"), std::string::npos) << error;
  EXPECT_THROW(CanStreamDecoder{o}, std::invalid_argument);
}

TEST(CanFrameLayout, ClassicSampleFrameHasTheDocumentedBytes) {
  CanFrameLayout layout;
  layout.module = 1;
  CanSampleEncoder encoder(layout);
  std::vector<CanFrame> frames;
  const std::int16_t set[] = {1, -2, 300, 32767};
  encoder.Add(set, frames);
  ASSERT_EQ(frames.size(), 1u);
  const CanFrame& f = frames[0];
  EXPECT_FALSE(f.fd);
  EXPECT_EQ(f.wire_size(), 16u);
  // Extended id: kind 0x08 in bits 28..24, module 1 in bits 23..18, sequence 0.
  EXPECT_EQ(f.raw.can_id, 0x88040000u);
  EXPECT_EQ(f.raw.len, 8);
  const std::uint8_t expected[] = {0x01, 0x00, 0xFE, 0xFF, 0x2C, 0x01, 0xFF, 0x7F};
  EXPECT_EQ(std::memcmp(f.raw.data, expected, 8), 0);
  // The second frame carries sequence 1.
  encoder.Add(set, frames);
  EXPECT_EQ(frames[1].raw.can_id, 0x88040001u);
}

TEST(CanFrameLayout, FdFrameCarriesEightSetsAndTheFirstSetsSequence) {
  CanFrameLayout layout;
  layout.fd = true;
  layout.module = 63;
  EXPECT_EQ(layout.sets_per_frame(), 8);
  EXPECT_EQ(layout.sample_payload(), 64);
  CanSampleEncoder encoder(layout);
  encoder.Skip((1u << 18) - 8);  // the frame before the sequence wraps
  const auto frames = test::Ramp(encoder, 0, 16);
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_TRUE(frames[0].fd);
  EXPECT_EQ(frames[0].wire_size(), 72u);
  EXPECT_EQ(frames[0].raw.len, 64);
  EXPECT_EQ(frames[0].raw.can_id, CAN_EFF_FLAG | 0x08000000u | (63u << 18) | 0x3FFF8u);
  EXPECT_EQ(frames[1].raw.can_id, CAN_EFF_FLAG | 0x08000000u | (63u << 18));  // wrapped to 0
  // Set 3 of the first frame: counts (3, -3, 9, 7) at bytes 24..31.
  const std::uint8_t set3[] = {0x03, 0x00, 0xFD, 0xFF, 0x09, 0x00, 0x07, 0x00};
  EXPECT_EQ(std::memcmp(frames[0].raw.data + 24, set3, 8), 0);
}

TEST(CanFrameLayout, StatusFrameCarriesTheNextFramedIndex) {
  CanFrameLayout layout;
  layout.fd = true;
  CanSampleEncoder encoder(layout);
  auto frames = test::Ramp(encoder, 0, 11);  // one frame of 8 sent, 3 sets waiting
  encoder.AddStatus(0x8002, 17, 130, frames);
  const CanFrame& s = frames.back();
  EXPECT_FALSE(s.fd);
  EXPECT_EQ(s.raw.can_id, 0x84040000u);
  const std::uint8_t expected[] = {0x08, 0x00, 0x00, 0x00, 0x02, 0x80, 17, 130};
  EXPECT_EQ(std::memcmp(s.raw.data, expected, 8), 0);
}

TEST(CanFrameLayout, InvalidLayoutsAreRefused) {
  std::string error;
  CanFrameLayout layout;
  layout.channels = 5;
  EXPECT_FALSE(layout.IsValid(&error));
  EXPECT_NE(error.find("5 channels"), std::string::npos);
  layout.fd = true;
  EXPECT_TRUE(layout.IsValid(&error));
  EXPECT_EQ(layout.sets_per_frame(), 6);    // 64 / 10
  EXPECT_EQ(layout.sample_payload(), 64);   // 60 bytes rounded up to a CAN FD length
  layout.module = 64;
  EXPECT_FALSE(layout.IsValid(&error));
  EXPECT_THROW(CanSampleEncoder{layout}, std::invalid_argument);
}

// The arithmetic of docs/can-acquisition.md, "Rates", done by hand there.
TEST(CanBus, FrameBitsMatchTheHandCount) {
  EXPECT_EQ(FrameBits(false, 8, true).nominal, 160);   // 118 stuffed + 29 stuff + 13
  EXPECT_EQ(FrameBits(false, 8, false).nominal, 131);
  const CanFrameBits fd = FrameBits(true, 64, true);
  EXPECT_EQ(fd.nominal, 56);   // 36 + 8 + 12
  EXPECT_EQ(fd.data, 679);     // 517 + 129 + 4 + 21 + 7 + 1
  EXPECT_EQ(FrameBits(true, 64, false).data, 550);
  EXPECT_NEAR(fd.Seconds({1e6, 5e6}), 191.8e-6, 1e-9);
}

TEST(CanBus, ClassicLayoutRateAtOneMegabit) {
  CanFrameLayout classic;
  const CanBitrates rates{1e6, 5e6};
  // 160 µs per frame at full load, no status: 6250 sets/s.
  EXPECT_NEAR(MaxSampleRate(classic, rates, 1.0, 0), 6250.0, 1e-6);
  // 2 kHz with a status frame every 200 sets is 32.16 % of the bus.
  EXPECT_NEAR(2000.0 / MaxSampleRate(classic, rates, 1.0, 200), 0.3216, 1e-9);
  CanFrameLayout fd = classic;
  fd.fd = true;
  EXPECT_NEAR(MaxSampleRate(fd, rates, 1.0, 0), 8.0 / 191.8e-6, 1e-3);
}

TEST(CanFrame, FromBytesAcceptsOnlyTheTwoStructSizesWithValidLengths) {
  std::array<std::uint8_t, 100> bytes{};
  for (std::size_t size = 0; size < bytes.size(); ++size) {
    const auto f = CanFrame::FromBytes({bytes.data(), size});
    EXPECT_EQ(f.has_value(), size == CAN_MTU || size == CANFD_MTU) << size;
  }
  bytes[4] = 9;  // len 9: not a classic frame, not a CAN FD length
  EXPECT_FALSE(CanFrame::FromBytes({bytes.data(), CAN_MTU}));
  EXPECT_FALSE(CanFrame::FromBytes({bytes.data(), CANFD_MTU}));
  bytes[4] = 12;
  ASSERT_TRUE(CanFrame::FromBytes({bytes.data(), CANFD_MTU}));
  EXPECT_TRUE(CanFrame::FromBytes({bytes.data(), CANFD_MTU})->fd);
}

}  // namespace
}  // namespace strut::daq
