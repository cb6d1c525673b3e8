// libFuzzer target: any bytes through the CAN frame decoder, as the UDP transport would hand them
// over. Built with clang by scripts/fuzz-can.sh (AddressSanitizer, UndefinedBehaviorSanitizer).
// The input is a sequence of units: a header byte (bits 0-1: 16-byte frame, 72-byte frame, or a
// datagram of any length given by the next byte; bits 2-7: time to the unit in 0.25 ms steps),
// then the unit's bytes.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "strut/daq/can_acquisition.h"

namespace {

strut::daq::CanAcquisitionOptions Options(bool fd) {
  strut::daq::CanAcquisitionOptions o;
  o.layout.fd = fd;
  o.layout.module = 1;
  o.sample_rate = fd ? 50000.0 : 2000.0;
  for (const char* name : {"stroke", "force", "pressure", "temperature"})
    o.channels.push_back({name, "1", strut::daq::Calibration::FromRange16(-1.0, 1.0)});
  return o;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  // The first byte picks the layout, so both decoders are explored.
  strut::daq::CanStreamDecoder decoder(Options(data[0] & 1));
  std::int64_t t = 1'000'000'000;
  decoder.Reset(t);
  strut::daq::AcquiredBlock block;
  std::uint64_t units = 0;
  for (std::size_t pos = 1; pos < size;) {
    const std::uint8_t header = data[pos++];
    std::size_t length = (header & 3) == 0 ? CAN_MTU : (header & 3) == 1 ? CANFD_MTU : 0;
    if (length == 0 && pos < size) length = data[pos++];
    if (length > size - pos) length = size - pos;
    t += static_cast<std::int64_t>(header >> 2) * 250'000;
    decoder.CheckStale(t, block);
    const auto frame = strut::daq::CanFrame::FromBytes({data + pos, length});
    pos += length;
    ++units;
    if (!frame) {
      decoder.AddMalformed(1, t, block);
      continue;
    }
    if (!decoder.Feed(*frame, t, block)) {
      decoder.Finish(block);
      block = {};
      if (!decoder.Feed(*frame, t, block)) __builtin_trap();  // a fresh block must take any frame
    }
  }
  decoder.Finish(block);
  const auto& s = decoder.stats();
  // Every unit is accounted for.
  if (s.frames + s.malformed_datagrams != units) __builtin_trap();
  return 0;
}
