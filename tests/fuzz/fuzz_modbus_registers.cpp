// libFuzzer target: any bytes as registers through every decoder of the controller's register
// map (daq/include/strut/daq/controller_registers.h). Built with clang by tests/fuzz/CMakeLists.txt
// with AddressSanitizer and UndefinedBehaviorSanitizer; a short run is part of ctest.
// The first byte chooses whether the set-point checksum is repaired, so that inputs get past the
// CRC into the mode, finiteness and range checks.
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "strut/daq/controller_registers.h"

using namespace strut::daq;
using namespace strut::daq::registers;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const bool repair = data[0] & 1;
  std::vector<std::uint16_t> words((size - 1) / 2);
  for (std::size_t i = 0; i < words.size(); ++i)
    words[i] = static_cast<std::uint16_t>((data[1 + 2 * i] << 8) | data[2 + 2 * i]);
  if (repair && words.size() == holding::kSetPointCount) words[holding::kChecksum] = SetPointChecksum(words);

  const auto set_point = DecodeSetPoint(words);
  if (set_point.ok()) {
    // Whatever is accepted is valid and encodes back to the same registers.
    if (!set_point.value->IsValid()) std::abort();
    const SetPointBlock again = EncodeSetPoint(*set_point.value, SequenceOf(words));
    if (std::memcmp(again.data(), words.data(), sizeof again) != 0) std::abort();
  } else if (set_point.refusal.message.empty()) {
    std::abort();
  }
  const std::size_t status_size = words.size() < input::kStatusCount ? words.size() : input::kStatusCount;
  const auto status = DecodeStatus(std::span<const std::uint16_t>(words.data(), status_size));
  if (status.ok()) {
    const StatusBlock again = EncodeStatus(*status.value);
    if (std::memcmp(again.data(), words.data(), sizeof again) != 0) std::abort();
  }
  const Refusal refusal = DecodeRefusal(words);
  for (char c : refusal.message)
    if (c < 0x20 || c >= 0x7F) std::abort();
  if (!words.empty()) DecodeCommand(words[0]);
  (void)HoldingName(words.empty() ? 0 : words[0]);
  (void)InputName(words.empty() ? 0 : words[0]);
  return 0;
}
