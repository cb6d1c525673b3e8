// strut bench acquisition: the CAN acquisition's software path over the UDP transport on loopback
// (study::RunCanStream). Printed: lost and corrupt sets, the receiver's CPU as a share of one core,
// and the rates the classic and CAN FD layouts allow on a real bus (docs/can-acquisition.md); with
// --pages, the live monitor under that load, without and with pages (docs/monitor.md).
#include <fmt/format.h>

#include <cmath>
#include <iostream>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "option_checks.h"
#include "output_files.h"
#include "strut/daq/can_acquisition.h"
#include "strut/study/acquisition.h"

namespace strut::tools {
namespace {

struct BenchAcquisition {
  double seconds = 5.0;
  double fd_rate = 50000.0;
  int pages = 0;
  int repeats = 3;
  std::string json_path;

  // The monitor fed by the receiving thread as a rig run feeds it, without and with `pages` pages
  // reading its stream, alternated; true when no run lost a sample.
  bool MonitorUnderLoad(nlohmann::json& report) const {
    std::cout << fmt::format("the live monitor under load: CAN FD at {:.0f} Hz, 4 channels, {:.0f} s a run, fed "
                             "every block by the receiving thread; 0 and {} pages (socket clients reading /events), "
                             "alternated {} times:\n",
                             fd_rate, seconds, pages, repeats);
    const study::MonitorLoad m = study::RunMonitorLoad(fd_rate, seconds, pages, repeats);
    nlohmann::json runs = nlohmann::json::array();
    std::cout << fmt::format("  {:>5} {:>10} {:>6} {:>13} {:>12} {:>9} {:>12} {:>10} {:>9}\n", "pages", "received",
                             "lost", "receiver CPU", "process CPU", "dropped", "updates/page", "MB pages", "page CPU");
    for (std::size_t k = 0; k < m.with_pages.size(); ++k) {
      for (const study::CanStreamRun* r : {&m.without_pages[k], &m.with_pages[k]}) {
        std::cout << fmt::format("  {:>5} {:>10} {:>6} {:>12.1f}% {:>11.1f}% {:>9} {:>12} {:>10.1f} {:>8.1f}%\n",
                                 *r->pages, r->received, r->lost, 100.0 * r->receiver_cpu, 100.0 * r->process_cpu,
                                 r->monitor_dropped, r->page_updates_min, r->page_bytes * 1e-6, 100.0 * r->page_cpu);
        runs.push_back({{"pages", *r->pages}, {"sent", r->sent}, {"received", r->received}, {"lost", r->lost},
                        {"wrong_values", r->wrong_values}, {"receiver_cpu_fraction", r->receiver_cpu},
                        {"process_cpu_fraction", r->process_cpu}, {"monitor_dropped_points", r->monitor_dropped},
                        {"page_updates_min", r->page_updates_min}, {"page_bytes", r->page_bytes},
                        {"page_cpu_fraction", r->page_cpu}});
      }
    }
    std::cout << fmt::format("  medians: receiver thread {:.1f} % -> {:.1f} % of one core (x{:.2f}), receiving process "
                             "(receiver, hub, server threads) {:.1f} % -> {:.1f} % (x{:.2f}); {} samples lost in all "
                             "runs\n",
                             100.0 * m.receiver_cpu_without, 100.0 * m.receiver_cpu_with,
                             m.receiver_cpu_with / m.receiver_cpu_without, 100.0 * m.process_cpu_without,
                             100.0 * m.process_cpu_with, m.process_cpu_with / m.process_cpu_without, m.lost);
    report["monitor_under_load"] = {{"rate_hz", fd_rate},
                                    {"seconds", seconds},
                                    {"pages", pages},
                                    {"repeats", repeats},
                                    {"runs", runs},
                                    {"lost", m.lost},
                                    {"median_receiver_cpu_without_pages", m.receiver_cpu_without},
                                    {"median_receiver_cpu_with_pages", m.receiver_cpu_with},
                                    {"median_process_cpu_without_pages", m.process_cpu_without},
                                    {"median_process_cpu_with_pages", m.process_cpu_with}};
    return m.lost == 0;
  }

  void Run() const {
    CheckOutputPath("--json", json_path, {});
    nlohmann::json report;
    const daq::CanBitrates bus{1e6, 5e6};
    daq::CanFrameLayout classic, fd;
    fd.fd = true;
    const int status_every_classic = 200;  // 10 Hz at 2 kHz
    const double classic_max = daq::MaxSampleRate(classic, bus, 1.0, status_every_classic);
    std::cout << "CAN layouts on a real bus (29-bit ids, worst-case bit stuffing, a status frame at 10 Hz):\n";
    std::cout << fmt::format("  classic 1 Mbit/s: {} bits per sample frame = {:.0f} us; at most {:.0f} sets/s of 4 "
                             "channels at 100 % bus load, {:.0f} at 50 %; 2 kHz uses {:.1f} % of the bus\n",
                             daq::FrameBits(false, 8, true).nominal, daq::FrameBits(false, 8, true).Seconds(bus) * 1e6,
                             classic_max, daq::MaxSampleRate(classic, bus, 0.5, status_every_classic),
                             100.0 * 2000.0 / classic_max);
    for (const double data_rate : {2e6, 5e6, 8e6}) {
      const daq::CanBitrates b{1e6, data_rate};
      std::cout << fmt::format("  CAN FD 1/{:.0f} Mbit/s: {:.1f} us per 64-byte frame; at most {:.0f} sets/s at 100 % "
                               "bus load, {:.0f} at 50 %\n",
                               data_rate / 1e6, daq::FrameBits(true, 64, true).Seconds(b) * 1e6,
                               daq::MaxSampleRate(fd, b, 1.0, 5000), daq::MaxSampleRate(fd, b, 0.5, 5000));
    }
    report["bus"] = {{"classic_frame_bits_worst", daq::FrameBits(false, 8, true).nominal},
                     {"classic_max_sets_per_s", classic_max},
                     {"fd_1_5_max_sets_per_s", daq::MaxSampleRate(fd, bus, 1.0, 5000)}};

    std::cout << fmt::format("software path over UDP on loopback ({:.0f} s each, real-time sender thread):\n", seconds);
    nlohmann::json runs = nlohmann::json::array();
    bool all_ok = true;
    for (const auto& [is_fd, rate] : {std::pair{true, fd_rate}, std::pair{false, std::floor(classic_max)}}) {
      const study::CanStreamRun r = study::RunCanStream(is_fd, rate, seconds);
      all_ok &= r.Clean() && r.receiver_cpu < 0.10;
      std::cout << fmt::format("  {} at {:.0f} Hz: {} sets sent, {} received, {} lost, {} corrupt, {} wrong values; "
                               "receiver CPU {:.1f} % of one core (target < 10 %: {}), sender {:.1f} %, median "
                               "block latency {:.1f} ms\n",
                               r.layout, r.rate, r.sent, r.received, r.lost, r.corrupt, r.wrong_values,
                               100.0 * r.receiver_cpu, r.receiver_cpu < 0.10 ? "met" : "MISSED", 100.0 * r.sender_cpu,
                               r.block_latency_ms);
      runs.push_back({{"layout", r.layout}, {"rate_hz", r.rate}, {"seconds", r.seconds}, {"sent", r.sent},
                      {"received", r.received}, {"lost", r.lost}, {"corrupt", r.corrupt},
                      {"wrong_values", r.wrong_values}, {"receiver_drops", r.drops},
                      {"receiver_cpu_fraction", r.receiver_cpu}, {"sender_cpu_fraction", r.sender_cpu},
                      {"median_block_latency_ms", r.block_latency_ms}});
    }
    report["runs"] = runs;
    if (pages > 0) all_ok &= MonitorUnderLoad(report);
    report["all_targets_met"] = all_ok;
    if (!json_path.empty()) {
      WriteJsonOutput(json_path, report);
    }
  }
};

}  // namespace

void RegisterBenchAcquisition(CLI::App& bench) {
  auto [sub, b] = AddCommand<BenchAcquisition>(
      bench, "acquisition",
      "CAN acquisition over UDP on loopback: lost samples and receiver CPU at 4 x 50 kHz (CAN FD) "
      "and at the classic layout's bus limit; the bus arithmetic");
  sub->add_option("--seconds", b->seconds, "Length of each stream.")->check(Between(0.5, 600.0))->capture_default_str();
  sub->add_option("--fd-rate", b->fd_rate, "Sample sets per second of the CAN FD stream.")
      ->check(Between(100.0, 400000.0))
      ->capture_default_str();
  sub->add_option("--pages", b->pages,
                  "Also run the live monitor under the CAN FD stream, fed by the receiving thread: lost samples and "
                  "CPU with 0 and with this many pages reading its event stream (docs/monitor.md).")
      ->check(Between(1, 64));
  sub->add_option("--repeats", b->repeats, "With --pages: runs without and with pages, alternated, this many times each.")
      ->check(Between(1, 20))
      ->capture_default_str();
  sub->add_option("--json", b->json_path, "Also write the figures as JSON.");
}

}  // namespace strut::tools
