// The CAN acquisition's software path over the UDP transport on loopback (`strut bench
// acquisition`, docs/can-acquisition.md): a sender thread plays a module in real time while the
// calling thread runs daq::CanAcquisition and checks every count; optionally with the live
// monitor (monitor/) fed from the receiving thread as the rig runner feeds it, and pages reading
// its event stream (docs/monitor.md "Under load").
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace strut::study {

struct CanStreamRun {
  std::string layout;  //!< in words
  double rate = 0.0, seconds = 0.0;
  std::uint64_t sent = 0, received = 0, lost = 0, corrupt = 0, wrong_values = 0, drops = 0;
  double receiver_cpu = 0.0, sender_cpu = 0.0;  //!< share of one core
  double block_latency_ms = 0.0;  //!< median age of a block's last set (by its timestamp) when returned
  // With the monitor:
  std::optional<int> pages;  //!< pages connected to its event stream; nullopt: no monitor
  //! The receiving process's CPU as a share of one core: the receiving thread, the monitor's hub
  //! and its server's threads (every thread but the sender's and the pages').
  double process_cpu = 0.0;
  std::uint64_t monitor_dropped = 0;  //!< points the hub did not take in time (MonitorFeed)
  std::uint64_t page_updates_min = 0;  //!< updates the page that got fewest received
  std::uint64_t page_bytes = 0;        //!< bytes of the event stream, all pages
  double page_cpu = 0.0;               //!< the pages' reading threads, share of one core, together
  bool Clean() const { return lost == 0 && wrong_values == 0 && corrupt == 0; }
};

//! Streams `rate` sample sets of four channels per second for `seconds` in the CAN FD (`fd`) or
//! the classic layout. With `pages`, the receiving thread feeds the live monitor (every block,
//! as the rig runner's on_block does) served on a loopback port, and that many clients read its
//! event stream (plain sockets reading /events as a browser's EventSource does, until the server
//! ends it). Throws what the sender thread threw (a socket it could not open, ...).
CanStreamRun RunCanStream(bool fd, double rate, double seconds, std::optional<int> pages = std::nullopt);

//! The monitor under load: the CAN FD stream at `rate` with the monitor, 0 pages and `pages`
//! pages, alternated `repeats` times (so a change of the machine's load hits both alike).
struct MonitorLoad {
  std::vector<CanStreamRun> without_pages, with_pages;
  //! Medians over the repeats of the receiving thread's and the process's CPU, and their ratios
  //! (with pages / without).
  double receiver_cpu_without = 0.0, receiver_cpu_with = 0.0, process_cpu_without = 0.0, process_cpu_with = 0.0;
  std::uint64_t lost = 0;  //!< over every run
};
MonitorLoad RunMonitorLoad(double rate, double seconds, int pages, int repeats);

}  // namespace strut::study
