// Encoding and decoding of the controller's register blocks (docs/register-map.md). Standard
// library only (the libFuzzer target builds this file with clang alone).
#include "strut/daq/controller_registers.h"

#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <utility>

#include "set_point_check.h"

namespace strut::daq::registers {

namespace {

struct RegisterName {
  std::uint16_t address;
  std::uint16_t width;
  std::string_view name;
};

constexpr RegisterName kHoldingNames[] = {
    {holding::kMode, 1, "mode"},
    {holding::kRampCycles, 1, "ramp_cycles"},
    {holding::kStaticPosition, 2, "static_position"},
    {holding::kAmplitude, 2, "amplitude"},
    {holding::kFrequency, 2, "frequency"},
    {holding::kStaticRate, 2, "static_rate"},
    {holding::kStrokeMin, 2, "stroke_min"},
    {holding::kStrokeMax, 2, "stroke_max"},
    {holding::kForceMin, 2, "force_min"},
    {holding::kForceMax, 2, "force_max"},
    {holding::kChecksum, 1, "checksum"},
    {holding::kSequence, 1, "sequence"},
    {holding::kCommand, 1, "command"},
    {holding::kClientHeartbeat, 1, "client_heartbeat"},
    {holding::kWatchdogMs, 1, "watchdog_ms"},
};

constexpr RegisterName kInputNames[] = {
    {input::kState, 1, "state"},
    {input::kMode, 1, "mode"},
    {input::kStatusWord, 1, "status_word"},
    {input::kFaultWord, 1, "fault_word"},
    {input::kAppliedSequence, 1, "applied_sequence"},
    {input::kHeartbeat, 1, "heartbeat"},
    {input::kStroke, 2, "stroke"},
    {input::kForce, 2, "force"},
    {input::kCommandValue, 2, "command"},
    {input::kCycles, 2, "cycles"},
    {input::kTimeMs, 2, "time_ms"},
    {input::kRefusalCode, 1, "refusal_code"},
    {input::kRefusalRegister, 1, "refusal_register"},
    {input::kRefusalText, input::kRefusalTextCount, "refusal_text"},
};

template <std::size_t N>
std::string Name(const char* kind, std::uint16_t address, const RegisterName (&names)[N]) {
  std::string text = std::string(kind) + " register " + std::to_string(address);
  for (const RegisterName& r : names)
    if (address >= r.address && address < r.address + r.width) return text + " (" + std::string(r.name) + ")";
  return text;
}

std::uint16_t HoldingAddressOf(std::string_view field) {
  for (const RegisterName& r : kHoldingNames)
    if (r.name == field) return r.address;
  return holding::kSetPointBlock;
}

template <class T>
Decoded<T> Refuse(RefusalCode code, std::uint16_t address, std::string message) {
  return Decoded<T>{std::nullopt, Refusal{code, address, std::move(message)}};
}

// The refusal of a `what` block ("set-point", "status") at `address` that is not `expected` registers long.
template <class T>
Decoded<T> RefuseLength(std::uint16_t address, const char* what, std::size_t size, std::size_t expected) {
  return Refuse<T>(RefusalCode::kBadLength, address,
                   std::string(what) + " block of " + std::to_string(size) + " registers, expected " +
                       std::to_string(expected));
}

float FloatAt(std::span<const std::uint16_t> block, std::uint16_t address) {
  return GetFloat(std::span<const std::uint16_t, 2>(block.data() + address, 2));
}

void PutFloatAt(std::span<std::uint16_t> block, std::uint16_t address, double value) {
  PutFloat(std::span<std::uint16_t, 2>(block.data() + address, 2), static_cast<float>(value));
}

// The set-point's float32 fields with their registers, one table for encoding and decoding.
// `S` is SetPoint or const SetPoint.
template <typename S>
auto SetPointFloats(S& s) {
  return std::array{std::pair{holding::kStaticPosition, &s.static_position},
                    std::pair{holding::kAmplitude, &s.amplitude},
                    std::pair{holding::kFrequency, &s.frequency},
                    std::pair{holding::kStaticRate, &s.static_rate},
                    std::pair{holding::kStrokeMin, &s.limits.stroke_min},
                    std::pair{holding::kStrokeMax, &s.limits.stroke_max},
                    std::pair{holding::kForceMin, &s.limits.force_min},
                    std::pair{holding::kForceMax, &s.limits.force_max}};
}

}  // namespace

std::string_view ToString(RefusalCode code) {
  switch (code) {
    case RefusalCode::kNone: return "none";
    case RefusalCode::kBadLength: return "wrong block length";
    case RefusalCode::kBadChecksum: return "checksum mismatch";
    case RefusalCode::kBadSequence: return "sequence 0";
    case RefusalCode::kBadMode: return "unknown mode";
    case RefusalCode::kNotFinite: return "not a finite number";
    case RefusalCode::kOutOfRange: return "out of range";
    case RefusalCode::kBadCommand: return "unknown command";
    case RefusalCode::kStateRefused: return "refused in this state";
    case RefusalCode::kDeviceFailure: return "device failure";
    case RefusalCode::kBadState: return "unknown state";
  }
  return "unknown refusal code";
}

std::string HoldingName(std::uint16_t address) { return Name("holding", address, kHoldingNames); }
std::string InputName(std::uint16_t address) { return Name("input", address, kInputNames); }

void PutFloat(std::span<std::uint16_t, 2> words, float value) { PutU32(words, std::bit_cast<std::uint32_t>(value)); }

float GetFloat(std::span<const std::uint16_t, 2> words) { return std::bit_cast<float>(GetU32(words)); }

void PutU32(std::span<std::uint16_t, 2> words, std::uint32_t value) {
  words[0] = static_cast<std::uint16_t>(value >> 16);
  words[1] = static_cast<std::uint16_t>(value & 0xFFFFu);
}

std::uint32_t GetU32(std::span<const std::uint16_t, 2> words) {
  return (static_cast<std::uint32_t>(words[0]) << 16) | words[1];
}

std::uint16_t Crc16Modbus(std::span<const std::uint8_t> bytes) {
  std::uint16_t crc = 0xFFFF;
  for (std::uint8_t b : bytes) {
    crc ^= b;
    for (int bit = 0; bit < 8; ++bit) crc = (crc & 1u) ? static_cast<std::uint16_t>((crc >> 1) ^ 0xA001u) : crc >> 1;
  }
  return crc;
}

std::uint16_t SetPointChecksum(std::span<const std::uint16_t> block) {
  std::array<std::uint8_t, 2 * (holding::kChecksum + 1)> bytes{};
  std::size_t n = 0;
  auto put = [&](std::uint16_t word) {
    bytes[n++] = static_cast<std::uint8_t>(word >> 8);
    bytes[n++] = static_cast<std::uint8_t>(word & 0xFF);
  };
  if (block.size() < holding::kSetPointCount) return 0;
  for (std::uint16_t a = 0; a < holding::kChecksum; ++a) put(block[a]);
  put(block[holding::kSequence]);
  return Crc16Modbus(std::span<const std::uint8_t>(bytes.data(), n));
}

std::uint16_t SequenceOf(std::span<const std::uint16_t> block) {
  return block.size() > holding::kSequence ? block[holding::kSequence] : 0;
}

SetPointBlock EncodeSetPoint(const SetPoint& s, std::uint16_t sequence) {
  SetPointBlock block{};
  block[holding::kMode] = static_cast<std::uint16_t>(s.mode);
  block[holding::kRampCycles] = static_cast<std::uint16_t>(s.ramp_cycles);
  for (const auto& [address, value] : SetPointFloats(s)) PutFloatAt(block, address, *value);
  block[holding::kSequence] = sequence;
  block[holding::kChecksum] = SetPointChecksum(block);
  return block;
}

Decoded<SetPoint> DecodeSetPoint(std::span<const std::uint16_t> block) {
  using R = RefusalCode;
  if (block.size() != holding::kSetPointCount)
    return RefuseLength<SetPoint>(holding::kSetPointBlock, "set-point", block.size(), holding::kSetPointCount);
  if (block[holding::kSequence] == 0)
    return Refuse<SetPoint>(R::kBadSequence, holding::kSequence, HoldingName(holding::kSequence) + " is 0, which is reserved");
  const std::uint16_t expected = SetPointChecksum(block);
  if (block[holding::kChecksum] != expected)
    return Refuse<SetPoint>(R::kBadChecksum, holding::kChecksum,
                            "half-written or corrupted block: " + HoldingName(holding::kChecksum) + " is " +
                                std::to_string(block[holding::kChecksum]) + ", the block gives " +
                                std::to_string(expected));
  const auto mode = ControlModeFrom(block[holding::kMode]);
  if (!mode)
    return Refuse<SetPoint>(R::kBadMode, holding::kMode,
                            HoldingName(holding::kMode) + " is " + std::to_string(block[holding::kMode]) +
                                ", neither stroke (1) nor force (2) control");
  SetPoint s;
  s.mode = *mode;
  s.ramp_cycles = block[holding::kRampCycles];
  for (const auto& [address, value] : SetPointFloats(s)) *value = FloatAt(block, address);
  if (const auto problem = detail::CheckSetPoint(s)) {
    const std::uint16_t address = HoldingAddressOf(problem->field);
    return Refuse<SetPoint>(problem->not_finite ? R::kNotFinite : R::kOutOfRange, address,
                            HoldingName(address) + ": " + problem->message);
  }
  return Decoded<SetPoint>{s, {}};
}

StatusBlock EncodeStatus(const ControllerStatus& s) {
  StatusBlock block{};
  block[input::kState] = static_cast<std::uint16_t>(s.state);
  block[input::kMode] = static_cast<std::uint16_t>(s.mode);
  block[input::kStatusWord] = s.status_word;
  block[input::kFaultWord] = s.fault_word;
  block[input::kAppliedSequence] = s.applied_sequence;
  block[input::kHeartbeat] = s.heartbeat;
  PutFloatAt(block, input::kStroke, s.stroke);
  PutFloatAt(block, input::kForce, s.force);
  PutFloatAt(block, input::kCommandValue, s.command);
  PutU32(std::span<std::uint16_t, 2>(block.data() + input::kCycles, 2), s.cycles);
  PutU32(std::span<std::uint16_t, 2>(block.data() + input::kTimeMs, 2), s.time_ms);
  return block;
}

Decoded<ControllerStatus> DecodeStatus(std::span<const std::uint16_t> block) {
  using R = RefusalCode;
  if (block.size() != input::kStatusCount)
    return RefuseLength<ControllerStatus>(input::kStatusBlock, "status", block.size(), input::kStatusCount);
  ControllerStatus s;
  const auto state = ControllerStateFrom(block[input::kState]);
  if (!state)
    return Refuse<ControllerStatus>(R::kBadState, input::kState,
                                    InputName(input::kState) + " is " + std::to_string(block[input::kState]) +
                                        ", which names no controller state");
  const auto mode = ControlModeFrom(block[input::kMode]);
  if (!mode)
    return Refuse<ControllerStatus>(R::kBadMode, input::kMode,
                                    InputName(input::kMode) + " is " + std::to_string(block[input::kMode]) +
                                        ", neither stroke (1) nor force (2) control");
  s.state = *state;
  s.mode = *mode;
  s.status_word = block[input::kStatusWord];
  s.fault_word = block[input::kFaultWord];
  s.applied_sequence = block[input::kAppliedSequence];
  s.heartbeat = block[input::kHeartbeat];
  for (std::uint16_t address : {input::kStroke, input::kForce, input::kCommandValue}) {
    const float value = FloatAt(block, address);
    if (!std::isfinite(value))
      return Refuse<ControllerStatus>(R::kNotFinite, address,
                                      InputName(address) + " is " + detail::Number(value) + ", not a finite number");
  }
  s.stroke = FloatAt(block, input::kStroke);
  s.force = FloatAt(block, input::kForce);
  s.command = FloatAt(block, input::kCommandValue);
  s.cycles = GetU32(std::span<const std::uint16_t, 2>(block.data() + input::kCycles, 2));
  s.time_ms = GetU32(std::span<const std::uint16_t, 2>(block.data() + input::kTimeMs, 2));
  return Decoded<ControllerStatus>{s, {}};
}

RefusalBlock EncodeRefusal(const Refusal& refusal) {
  RefusalBlock block{};
  block[0] = static_cast<std::uint16_t>(refusal.code);
  block[1] = refusal.address;
  const std::size_t text = input::kRefusalText - input::kRefusalBlock;
  for (std::size_t i = 0; i < refusal.message.size() && i < 2u * input::kRefusalTextCount; ++i) {
    const unsigned char c = static_cast<unsigned char>(refusal.message[i]);
    const std::uint16_t byte = (c >= 0x20 && c < 0x7F) ? c : '?';
    block[text + i / 2] |= static_cast<std::uint16_t>(i % 2 == 0 ? byte << 8 : byte);
  }
  return block;
}

Refusal DecodeRefusal(std::span<const std::uint16_t> block) {
  Refusal refusal;
  if (block.size() >= 1) refusal.code = static_cast<RefusalCode>(block[0]);
  if (block.size() >= 2) refusal.address = block[1];
  const std::size_t text = input::kRefusalText - input::kRefusalBlock;
  for (std::size_t i = text; i < block.size() && i < text + input::kRefusalTextCount; ++i) {
    for (int shift : {8, 0}) {
      const unsigned char c = static_cast<unsigned char>((block[i] >> shift) & 0xFF);
      if (c == 0) return refusal;
      refusal.message += (c >= 0x20 && c < 0x7F) ? static_cast<char>(c) : '?';
    }
  }
  return refusal;
}

Decoded<ControllerCommand> DecodeCommand(std::uint16_t value) {
  if (const auto command = ControllerCommandFrom(value)) return Decoded<ControllerCommand>{*command, {}};
  return Refuse<ControllerCommand>(RefusalCode::kBadCommand, holding::kCommand,
                                   HoldingName(holding::kCommand) + " is " + std::to_string(value) +
                                       ", which names no command (1 arm, 2 run, 3 stop, 4 disarm, 5 reset-faults)");
}

}  // namespace strut::daq::registers
