// The CAN acquisition's software path over the UDP transport on loopback (`strut bench
// acquisition`, docs/can-acquisition.md): a sender thread plays a module in real time while the
// calling thread runs daq::CanAcquisition and checks every count.
#pragma once

#include <cstdint>
#include <string>

namespace strut::study {

struct CanStreamRun {
  std::string layout;  //!< in words
  double rate = 0.0, seconds = 0.0;
  std::uint64_t sent = 0, received = 0, lost = 0, corrupt = 0, wrong_values = 0, drops = 0;
  double receiver_cpu = 0.0, sender_cpu = 0.0;  //!< share of one core
  double block_latency_ms = 0.0;  //!< median age of a block's last set (by its timestamp) when returned
  bool Clean() const { return lost == 0 && wrong_values == 0 && corrupt == 0; }
};

//! Streams `rate` sample sets of four channels per second for `seconds` in the CAN FD (`fd`) or
//! the classic layout. Throws what the sender thread threw (a socket it could not open, ...).
CanStreamRun RunCanStream(bool fd, double rate, double seconds);

}  // namespace strut::study
