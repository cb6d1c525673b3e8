// The controller's register map: encoding against independent references (the CRC check value
// of the CRC catalogue, libmodbus's own float conversion), refusals that name the register, and
// a deterministic fuzz loop through every decoder.
#include <gtest/gtest.h>
#include <modbus/modbus.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <random>
#include <string>

#include "set_points.h"
#include "strut/daq/controller_registers.h"

namespace strut::daq::registers {
namespace {

SetPoint TypicalSetPoint() { return strut::test::ExperimentHSetPoint(/*ramp_cycles=*/3); }

//! The set-point as the registers carry it (float32).
// Through a volatile float: GCC 12's SLP vectorizer at -O3 dropped the double -> float -> double
// round trip of two of these fields when written as plain casts (seen here; -fno-tree-slp-vectorize
// restores it).
double F32(double v) {
  volatile float f = static_cast<float>(v);
  return f;
}
SetPoint Rounded(const SetPoint& s) {
  SetPoint r = s;
  r.static_position = F32(s.static_position);
  r.amplitude = F32(s.amplitude);
  r.frequency = F32(s.frequency);
  r.static_rate = F32(s.static_rate);
  r.limits = {F32(s.limits.stroke_min), F32(s.limits.stroke_max), F32(s.limits.force_min), F32(s.limits.force_max)};
  return r;
}

TEST(ModbusRegisters, Crc16MatchesTheCatalogueCheckValue) {
  // CRC-16/MODBUS check value from the CRC catalogue (reveng): "123456789" -> 0x4B37.
  const char* text = "123456789";
  EXPECT_EQ(Crc16Modbus(std::span(reinterpret_cast<const std::uint8_t*>(text), 9)), 0x4B37);
}

TEST(ModbusRegisters, FloatsAreHighWordFirstAsLibmodbusAbcd) {
  for (float value : {1.0f, -2.5f, 0.034f, 4.5e4f, -1e-7f, std::numeric_limits<float>::max()}) {
    std::array<std::uint16_t, 2> words{};
    PutFloat(words, value);
    EXPECT_EQ(modbus_get_float_abcd(words.data()), value);  // libmodbus, an independent implementation
    EXPECT_EQ(GetFloat(words), value);
    std::uint32_t bits;
    std::memcpy(&bits, &value, 4);
    EXPECT_EQ(words[0], bits >> 16);
    EXPECT_EQ(words[1], bits & 0xFFFF);
  }
  std::array<std::uint16_t, 2> one{};
  PutFloat(one, 1.0f);
  EXPECT_EQ(one[0], 0x3F80);
  EXPECT_EQ(one[1], 0x0000);
  std::array<std::uint16_t, 2> u32{};
  PutU32(u32, 0x12345678u);
  EXPECT_EQ(u32[0], 0x1234);
  EXPECT_EQ(u32[1], 0x5678);
  EXPECT_EQ(GetU32(u32), 0x12345678u);
}

TEST(ModbusRegisters, SetPointRoundTripsThroughItsBlock) {
  SetPoint force = TypicalSetPoint();
  force.mode = ControlMode::kForce;
  force.static_position = 1.0e4;
  force.amplitude = 2.0e4;
  force.static_rate = 5.0e3;
  for (const SetPoint& s : {TypicalSetPoint(), force}) {
    const SetPointBlock block = EncodeSetPoint(s, 7);
    EXPECT_EQ(block[holding::kSequence], 7);
    EXPECT_EQ(block[holding::kMode], static_cast<std::uint16_t>(s.mode));
    EXPECT_EQ(block[holding::kRampCycles], 3);
    EXPECT_EQ(modbus_get_float_abcd(&block[holding::kAmplitude]), static_cast<float>(s.amplitude));
    EXPECT_EQ(modbus_get_float_abcd(&block[holding::kForceMax]), 4.5e4f);
    const auto decoded = DecodeSetPoint(block);
    ASSERT_TRUE(decoded.ok()) << decoded.refusal.message;
    EXPECT_EQ(*decoded.value, Rounded(s));
  }
}

TEST(ModbusRegisters, ChecksumCoversTheBlockAndTheSequence) {
  SetPointBlock block = EncodeSetPoint(TypicalSetPoint(), 9);
  // Any one register changed, the sequence included, breaks the checksum.
  for (std::uint16_t a = 0; a < holding::kSetPointCount; ++a) {
    if (a == holding::kChecksum) continue;
    SetPointBlock changed = block;
    changed[a] ^= 0x0100;
    const auto decoded = DecodeSetPoint(changed);
    ASSERT_FALSE(decoded.ok()) << HoldingName(a);
    EXPECT_EQ(decoded.refusal.code, RefusalCode::kBadChecksum);
    EXPECT_EQ(decoded.refusal.address, holding::kChecksum);
    EXPECT_NE(decoded.refusal.message.find("half-written"), std::string::npos);
  }
}

struct Case {
  const char* what;
  std::function<void(SetPoint&)> change;
  RefusalCode code;
  std::uint16_t address;
  const char* says;
};

TEST(ModbusRegisters, BadValuesAreRefusedNamingTheirRegister) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<Case> cases = {
      {"NaN amplitude", [&](SetPoint& s) { s.amplitude = nan; }, RefusalCode::kNotFinite, holding::kAmplitude, "amplitude"},
      {"infinite static", [](SetPoint& s) { s.static_position = INFINITY; }, RefusalCode::kNotFinite,
       holding::kStaticPosition, "static_position"},
      {"NaN force limit", [&](SetPoint& s) { s.limits.force_max = nan; }, RefusalCode::kNotFinite, holding::kForceMax,
       "force_max"},
      {"negative amplitude", [](SetPoint& s) { s.amplitude = -0.01; }, RefusalCode::kOutOfRange, holding::kAmplitude,
       "negative"},
      {"sine beyond the stroke limit", [](SetPoint& s) { s.amplitude = 0.3; }, RefusalCode::kOutOfRange,
       holding::kAmplitude, "stroke limits"},
      {"static outside the limits", [](SetPoint& s) { s.static_position = 0.4; }, RefusalCode::kOutOfRange,
       holding::kStaticPosition, "static_position"},
      {"frequency too high", [](SetPoint& s) { s.frequency = 500; }, RefusalCode::kOutOfRange, holding::kFrequency,
       "200 Hz"},
      {"amplitude without frequency", [](SetPoint& s) { s.frequency = 0; }, RefusalCode::kOutOfRange,
       holding::kFrequency, "0 Hz"},
      {"ramp too long", [](SetPoint& s) { s.ramp_cycles = 5000; }, RefusalCode::kOutOfRange, holding::kRampCycles,
       "ramp_cycles"},
      {"zero static rate", [](SetPoint& s) { s.static_rate = 0; }, RefusalCode::kOutOfRange, holding::kStaticRate,
       "static_rate"},
      {"limits reversed", [](SetPoint& s) { s.limits.stroke_max = -0.1; }, RefusalCode::kOutOfRange,
       holding::kStrokeMax, "stroke_min"},
      {"absurd force limit", [](SetPoint& s) { s.limits.force_min = -1e9; }, RefusalCode::kOutOfRange,
       holding::kForceMin, "force_min"},
  };
  for (const Case& c : cases) {
    SetPoint s = TypicalSetPoint();
    c.change(s);
    std::string why;
    EXPECT_FALSE(s.IsValid(&why)) << c.what;
    // The block is built by hand: EncodeSetPoint requires a valid set-point.
    SetPointBlock block = EncodeSetPoint(TypicalSetPoint(), 5);
    block[holding::kRampCycles] = static_cast<std::uint16_t>(s.ramp_cycles);
    PutFloat(std::span<std::uint16_t, 2>(&block[holding::kStaticPosition], 2), static_cast<float>(s.static_position));
    PutFloat(std::span<std::uint16_t, 2>(&block[holding::kAmplitude], 2), static_cast<float>(s.amplitude));
    PutFloat(std::span<std::uint16_t, 2>(&block[holding::kFrequency], 2), static_cast<float>(s.frequency));
    PutFloat(std::span<std::uint16_t, 2>(&block[holding::kStaticRate], 2), static_cast<float>(s.static_rate));
    PutFloat(std::span<std::uint16_t, 2>(&block[holding::kStrokeMax], 2), static_cast<float>(s.limits.stroke_max));
    PutFloat(std::span<std::uint16_t, 2>(&block[holding::kForceMin], 2), static_cast<float>(s.limits.force_min));
    PutFloat(std::span<std::uint16_t, 2>(&block[holding::kForceMax], 2), static_cast<float>(s.limits.force_max));
    block[holding::kChecksum] = SetPointChecksum(block);
    const auto decoded = DecodeSetPoint(block);
    ASSERT_FALSE(decoded.ok()) << c.what;
    EXPECT_EQ(decoded.refusal.code, c.code) << c.what << ": " << decoded.refusal.message;
    EXPECT_EQ(decoded.refusal.address, c.address) << c.what << ": " << decoded.refusal.message;
    EXPECT_NE(decoded.refusal.message.find(c.says), std::string::npos) << decoded.refusal.message;
    EXPECT_NE(decoded.refusal.message.find("holding register " + std::to_string(c.address)), std::string::npos)
        << decoded.refusal.message;
  }
}

TEST(ModbusRegisters, ShortLongZeroSequenceAndUnknownModeAreRefused) {
  const SetPointBlock good = EncodeSetPoint(TypicalSetPoint(), 3);
  EXPECT_EQ(DecodeSetPoint(std::span(good.data(), 19)).refusal.code, RefusalCode::kBadLength);
  EXPECT_EQ(DecodeSetPoint(std::span<const std::uint16_t>()).refusal.code, RefusalCode::kBadLength);
  std::vector<std::uint16_t> longer(good.begin(), good.end());
  longer.push_back(0);
  EXPECT_EQ(DecodeSetPoint(longer).refusal.code, RefusalCode::kBadLength);
  SetPointBlock zero = good;
  zero[holding::kSequence] = 0;
  zero[holding::kChecksum] = SetPointChecksum(zero);
  EXPECT_EQ(DecodeSetPoint(zero).refusal.code, RefusalCode::kBadSequence);
  SetPointBlock mode = good;
  mode[holding::kMode] = 3;
  mode[holding::kChecksum] = SetPointChecksum(mode);
  const auto decoded = DecodeSetPoint(mode);
  EXPECT_EQ(decoded.refusal.code, RefusalCode::kBadMode);
  EXPECT_NE(decoded.refusal.message.find("holding register 0 (mode) is 3"), std::string::npos) << decoded.refusal.message;
}

TEST(ModbusRegisters, StatusRoundTripsAndRefusesNaNAndUnknownState) {
  ControllerStatus s;
  s.state = ControllerState::kStopping;
  s.mode = ControlMode::kForce;
  s.status_word = 0x0025;
  s.fault_word = fault_bits::kForceLimit;
  s.applied_sequence = 65535;
  s.heartbeat = 12345;
  s.stroke = 0.125f;
  s.force = -31250.5f;
  s.command = 1.0e4f;
  s.cycles = 70000;
  s.time_ms = 4000000000u;
  const StatusBlock block = EncodeStatus(s);
  EXPECT_EQ(block[input::kCycles], 1);  // 70000 = 0x00011170
  EXPECT_EQ(block[input::kCycles + 1], 0x1170);
  const auto decoded = DecodeStatus(block);
  ASSERT_TRUE(decoded.ok()) << decoded.refusal.message;
  EXPECT_EQ(*decoded.value, s);

  StatusBlock nan = block;
  PutFloat(std::span<std::uint16_t, 2>(&nan[input::kForce], 2), std::numeric_limits<float>::quiet_NaN());
  const auto refused = DecodeStatus(nan);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.refusal.address, input::kForce);
  EXPECT_NE(refused.refusal.message.find("input register 8 (force)"), std::string::npos) << refused.refusal.message;
  StatusBlock state = block;
  state[input::kState] = 9;
  EXPECT_EQ(DecodeStatus(state).refusal.code, RefusalCode::kBadState);
  EXPECT_EQ(DecodeStatus(std::span(block.data(), 15)).refusal.code, RefusalCode::kBadLength);
}

TEST(ModbusRegisters, RefusalTextIsPrintableAsciiOfAtMost120Bytes) {
  const Refusal r{RefusalCode::kStateRefused, holding::kCommand, "run refused: not armed\n\xff" + std::string(150, 'x')};
  const Refusal back = DecodeRefusal(EncodeRefusal(r));
  EXPECT_EQ(back.code, r.code);
  EXPECT_EQ(back.address, r.address);
  EXPECT_EQ(back.message.size(), 120u);
  EXPECT_EQ(back.message.substr(0, 24), "run refused: not armed??");
  EXPECT_EQ(DecodeRefusal(EncodeRefusal({RefusalCode::kBadChecksum, 18, "short"})).message, "short");
}

TEST(ModbusRegisters, CommandRegisterNamesACommandOrIsRefused) {
  EXPECT_EQ(*DecodeCommand(2).value, ControllerCommand::kRun);
  for (std::uint16_t bad : {0, 6, 65535}) {
    const auto d = DecodeCommand(bad);
    ASSERT_FALSE(d.ok());
    EXPECT_EQ(d.refusal.address, holding::kCommand);
  }
}

// A million register blocks, random and mutated from valid ones (half of the mutants with their
// checksum repaired so that they reach the range checks), through every decoder. Whatever is
// accepted must be valid and encode back to the very same registers.
TEST(ModbusRegisters, FuzzedBlocksNeverCrashAndWhatIsAcceptedReencodesExactly) {
  std::mt19937_64 rng(20260101);
  std::uniform_int_distribution<int> word(0, 0xFFFF);
  std::uniform_int_distribution<int> small(0, 7);
  const SetPointBlock seed_blocks[] = {EncodeSetPoint(TypicalSetPoint(), 1), [] {
                                         SetPoint f = TypicalSetPoint();
                                         f.mode = ControlMode::kForce;
                                         f.static_position = 0;
                                         f.amplitude = 1e4;
                                         return EncodeSetPoint(f, 2);
                                       }()};
  ControllerStatus seed_status;
  seed_status.state = ControllerState::kRunning;
  seed_status.stroke = 0.1;
  seed_status.force = 2e4;
  const StatusBlock status_seed = EncodeStatus(seed_status);
  std::vector<std::uint16_t> status_block;
  std::map<RefusalCode, long> refusals;
  long accepted = 0, statuses = 0;
  const auto start = std::chrono::steady_clock::now();
  std::vector<std::uint16_t> block;
  for (long i = 0; i < 1000000; ++i) {
    const int kind = static_cast<int>(i % 4);
    if (kind == 0) {  // random length and content
      block.resize(static_cast<std::size_t>(word(rng) % 40));
      for (auto& w : block) w = static_cast<std::uint16_t>(word(rng));
    } else {  // a valid block with a few registers or bits changed
      const SetPointBlock& seed = seed_blocks[i % 2];
      block.assign(seed.begin(), seed.end());
      for (int m = 0, n = 1 + small(rng) % 3; m < n; ++m) {
        const std::size_t at = static_cast<std::size_t>(word(rng)) % block.size();
        if (small(rng) < 4)
          block[at] ^= static_cast<std::uint16_t>(1u << (word(rng) % 16));
        else
          block[at] = static_cast<std::uint16_t>(word(rng));
      }
      if (kind >= 2) block[holding::kChecksum] = SetPointChecksum(block);
    }
    const auto decoded = DecodeSetPoint(block);
    if (decoded.ok()) {
      ++accepted;
      ASSERT_TRUE(decoded.value->IsValid());
      const SetPointBlock again = EncodeSetPoint(*decoded.value, SequenceOf(block));
      ASSERT_TRUE(std::equal(again.begin(), again.end(), block.begin(), block.end())) << "block " << i;
    } else {
      ++refusals[decoded.refusal.code];
      ASSERT_FALSE(decoded.refusal.message.empty());
    }
    if (kind == 0) {
      status_block.assign(block.begin(), block.begin() + std::min<std::size_t>(block.size(), input::kStatusCount));
    } else {
      status_block.assign(status_seed.begin(), status_seed.end());
      status_block[static_cast<std::size_t>(word(rng)) % status_block.size()] = static_cast<std::uint16_t>(word(rng));
    }
    const auto status = DecodeStatus(status_block);
    if (status.ok()) {
      ++statuses;
      const StatusBlock again = EncodeStatus(*status.value);
      ASSERT_TRUE(std::equal(again.begin(), again.end(), status_block.begin(), status_block.end()));
    }
    const Refusal refusal = DecodeRefusal(block);
    for (char c : refusal.message) ASSERT_TRUE(c >= 0x20 && c < 0x7F);
    DecodeCommand(block.empty() ? 0 : block[0]);
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("fuzz: 1e6 blocks in %.2f s; %ld set-points and %ld statuses accepted\n", seconds, accepted, statuses);
  // The loop reached every stage of the decoder, not only the first check.
  EXPECT_GT(accepted, 1000);
  EXPECT_GT(statuses, 1000);
  for (RefusalCode code : {RefusalCode::kBadLength, RefusalCode::kBadChecksum, RefusalCode::kBadMode,
                           RefusalCode::kNotFinite, RefusalCode::kOutOfRange, RefusalCode::kBadSequence})
    EXPECT_GT(refusals[code], 0) << ToString(code);
}

}  // namespace
}  // namespace strut::daq::registers
