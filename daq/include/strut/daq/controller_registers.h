// The Modbus register map of the actuator controller (docs/register-map.md) and the pure
// encoding and decoding of its blocks. No I/O here: the client (ModbusController), the server
// (ModbusControllerServer), the fuzz tests and any other peer share these functions. Decoding
// accepts any registers of any length and either returns a valid value or a refusal that names
// the register; it never reads out of bounds and never lets NaN or an out-of-range value through.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "strut/daq/controller.h"

namespace strut::daq::registers {

// Addresses are Modbus PDU addresses (0-based; holding register 0 is "40001" in the 1-based
// convention). 32-bit values take two registers, the high word first (big-endian word order,
// "ABCD", libmodbus's modbus_get_float_abcd, pymodbus's Endian.Big for byte and word order).
// Physical values are IEEE-754 float32 in SI units (scale 1).

//! Holding registers (read/write, function codes 3, 6, 16).
namespace holding {
inline constexpr std::uint16_t kMode = 0;             //!< u16, ControlMode
inline constexpr std::uint16_t kRampCycles = 1;       //!< u16, whole cycles
inline constexpr std::uint16_t kStaticPosition = 2;   //!< f32, m or N
inline constexpr std::uint16_t kAmplitude = 4;        //!< f32, m or N
inline constexpr std::uint16_t kFrequency = 6;        //!< f32, Hz
inline constexpr std::uint16_t kStaticRate = 8;       //!< f32, m/s or N/s
inline constexpr std::uint16_t kStrokeMin = 10;       //!< f32, m
inline constexpr std::uint16_t kStrokeMax = 12;       //!< f32, m
inline constexpr std::uint16_t kForceMin = 14;        //!< f32, N
inline constexpr std::uint16_t kForceMax = 16;        //!< f32, N
inline constexpr std::uint16_t kChecksum = 18;        //!< u16, CRC-16/MODBUS of registers 0-17 and 19
inline constexpr std::uint16_t kSequence = 19;        //!< u16, commit register, 1..65535
inline constexpr std::uint16_t kCommand = 20;         //!< u16, ControllerCommand; each write executes
inline constexpr std::uint16_t kClientHeartbeat = 21; //!< u16, any change is a beat
inline constexpr std::uint16_t kWatchdogMs = 22;      //!< u16, ms, 0 = watchdog off
inline constexpr std::uint16_t kSetPointBlock = 0;    //!< first register of the set-point block
inline constexpr std::uint16_t kSetPointCount = 20;   //!< registers 0-19, written in one request
inline constexpr std::uint16_t kCount = 23;
}  // namespace holding

//! Input registers (read-only, function code 4).
namespace input {
inline constexpr std::uint16_t kState = 0;            //!< u16, ControllerState
inline constexpr std::uint16_t kMode = 1;             //!< u16, ControlMode in force
inline constexpr std::uint16_t kStatusWord = 2;       //!< u16, status_bits
inline constexpr std::uint16_t kFaultWord = 3;        //!< u16, fault_bits
inline constexpr std::uint16_t kAppliedSequence = 4;  //!< u16
inline constexpr std::uint16_t kHeartbeat = 5;        //!< u16, +1 every server tick
inline constexpr std::uint16_t kStroke = 6;           //!< f32, m
inline constexpr std::uint16_t kForce = 8;            //!< f32, N
inline constexpr std::uint16_t kCommandValue = 10;    //!< f32, m or N
inline constexpr std::uint16_t kCycles = 12;          //!< u32
inline constexpr std::uint16_t kTimeMs = 14;          //!< u32, ms
inline constexpr std::uint16_t kStatusBlock = 0;      //!< the status block, read in one request
inline constexpr std::uint16_t kStatusCount = 16;
inline constexpr std::uint16_t kRefusalCode = 16;     //!< u16, RefusalCode of the last refused write
inline constexpr std::uint16_t kRefusalRegister = 17; //!< u16, holding register it was about
inline constexpr std::uint16_t kRefusalText = 18;     //!< 60 registers: 120 bytes ASCII, NUL padded
inline constexpr std::uint16_t kRefusalTextCount = 60;
inline constexpr std::uint16_t kRefusalBlock = 16;    //!< code, register and text, read in one request
inline constexpr std::uint16_t kRefusalCount = 62;
inline constexpr std::uint16_t kCount = 78;
}  // namespace input

//! Why a write was refused (input register kRefusalCode).
enum class RefusalCode : std::uint16_t {
  kNone = 0,
  kBadLength = 1,      //!< a block of the wrong number of registers
  kBadChecksum = 2,    //!< the checksum does not match the block: half-written or corrupted
  kBadSequence = 3,    //!< sequence 0 (reserved for "nothing written yet")
  kBadMode = 4,        //!< a mode register that names no ControlMode
  kNotFinite = 5,      //!< NaN or infinity
  kOutOfRange = 6,     //!< a value outside its range (SetPoint::IsValid)
  kBadCommand = 7,     //!< a command register that names no ControllerCommand
  kStateRefused = 8,   //!< the controller's state does not allow it (the backend's reason)
  kDeviceFailure = 9,  //!< the backend failed
  kBadState = 10,      //!< a status block whose state register names no ControllerState
};
std::string_view ToString(RefusalCode code);

//! A refused block or write: the code, the register it is about and a sentence for people.
struct Refusal {
  RefusalCode code = RefusalCode::kNone;
  std::uint16_t address = 0;
  std::string message;
};

//! The value decoded, or the refusal.
template <class T>
struct Decoded {
  std::optional<T> value;
  Refusal refusal;
  bool ok() const { return value.has_value(); }
};

//! Name of a register for messages, e.g. "holding register 4 (amplitude)".
std::string HoldingName(std::uint16_t address);
std::string InputName(std::uint16_t address);

//! float32 as two registers, high word first, and back (bit exact, NaN included).
void PutFloat(std::span<std::uint16_t, 2> words, float value);
float GetFloat(std::span<const std::uint16_t, 2> words);
void PutU32(std::span<std::uint16_t, 2> words, std::uint32_t value);
std::uint32_t GetU32(std::span<const std::uint16_t, 2> words);

//! CRC-16/MODBUS (poly 0xA001 reflected, init 0xFFFF) over bytes ("123456789" gives 0x4B37).
std::uint16_t Crc16Modbus(std::span<const std::uint8_t> bytes);
//! The checksum register of a set-point block: CRC-16/MODBUS of registers 0-17 and then 19
//! (the sequence), each register high byte first. `block` must hold holding::kSetPointCount.
std::uint16_t SetPointChecksum(std::span<const std::uint16_t> block);

using SetPointBlock = std::array<std::uint16_t, holding::kSetPointCount>;
using StatusBlock = std::array<std::uint16_t, input::kStatusCount>;
using RefusalBlock = std::array<std::uint16_t, input::kRefusalCount>;

//! The block of registers 0-19 with checksum and sequence. Values are rounded to float32.
//! @pre set_point.IsValid(), sequence != 0.
SetPointBlock EncodeSetPoint(const SetPoint& set_point, std::uint16_t sequence);
//! Checks length, sequence, checksum, mode, finiteness and ranges, in that order.
Decoded<SetPoint> DecodeSetPoint(std::span<const std::uint16_t> block);
//! The sequence register of a block (0 for a block too short to have one).
std::uint16_t SequenceOf(std::span<const std::uint16_t> block);

StatusBlock EncodeStatus(const ControllerStatus& status);
//! Refuses a wrong length, an unknown state or mode, and a non-finite stroke, force or command.
Decoded<ControllerStatus> DecodeStatus(std::span<const std::uint16_t> block);

//! The refusal registers (code, register, text; the text cut to 120 bytes of printable ASCII).
RefusalBlock EncodeRefusal(const Refusal& refusal);
//! Any registers: bytes outside printable ASCII become '?', the text stops at the first NUL.
Refusal DecodeRefusal(std::span<const std::uint16_t> block);

//! The command register's value, or the refusal.
Decoded<ControllerCommand> DecodeCommand(std::uint16_t value);

}  // namespace strut::daq::registers
