// strut bench acquisition: the CAN acquisition's software path over the UDP transport on
// loopback. A sender thread plays a module in real time; the calling thread runs CanAcquisition
// and checks every count. Printed: lost and corrupt sets, the receiver's CPU as a share of one
// core, and the rates the classic and CAN FD layouts allow on a real bus (docs/can-acquisition.md).
#include <fmt/format.h>
#include <time.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <iostream>
#include <nlohmann/json.hpp>
#include <thread>

#include "commands.h"
#include "output_files.h"
#include "strut/daq/can_acquisition.h"
#include "option_checks.h"

namespace strut::tools {
namespace {

double ThreadCpuSeconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

//! The count channel c of sample set i carries: a different sine per channel, deterministic.
std::int16_t Expected(std::uint64_t i, int c) {
  return static_cast<std::int16_t>(std::lround(20000.0 * std::sin(0.001 * static_cast<double>(i) * (c + 1) + c)));
}

struct RunResult {
  std::string layout;
  double rate = 0.0, seconds = 0.0;
  std::uint64_t sent = 0, received = 0, lost = 0, corrupt = 0, wrong_values = 0, drops = 0;
  double receiver_cpu = 0.0, sender_cpu = 0.0;  //!< share of one core
  double block_latency_ms = 0.0;  //!< median age of a block's last set (by its timestamp) when returned
};

RunResult RunStream(bool fd, double rate, double seconds) {
  daq::CanAcquisitionOptions options;
  options.layout.fd = fd;
  options.sample_rate = rate;
  for (const char* name : {"stroke", "force", "pressure", "temperature"})
    options.channels.push_back({name, "1", daq::Calibration::FromRange16(-1.0, 1.0)});
  auto receiver = daq::UdpCanTransport::Listen("127.0.0.1", 0);
  const std::uint16_t port = receiver->local_port();
  daq::CanAcquisition acquisition(std::move(receiver), options);
  acquisition.Start();

  const std::uint64_t total = static_cast<std::uint64_t>(rate * seconds);
  std::atomic<double> sender_cpu{0.0};
  std::atomic<bool> sender_failed{false};
  std::thread sender_thread([&] {
    try {
      daq::CanAcquisitionSender sender(daq::UdpCanTransport::Connect("127.0.0.1", port), options.layout,
                                       static_cast<int>(rate / 10));
      sender.flush_sets = ~std::size_t{0};  // flushed by the 1 ms ticks below
      const double cpu0 = ThreadCpuSeconds();
      const auto start = std::chrono::steady_clock::now();
      std::uint64_t sent = 0;
      std::int16_t set[4];
      for (int tick = 1; sent < total; ++tick) {
        std::this_thread::sleep_until(start + std::chrono::milliseconds(tick));
        const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        const std::uint64_t due = std::min<std::uint64_t>(total, static_cast<std::uint64_t>(elapsed * rate));
        for (; sent < due; ++sent) {
          for (int c = 0; c < 4; ++c) set[c] = Expected(sent, c);
          sender.Add(set);
        }
        sender.Flush();
      }
      sender_cpu = (ThreadCpuSeconds() - cpu0) / std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    } catch (const std::exception& e) {
      std::cerr << "sender: " << e.what() << "\n";
      sender_failed = true;
    }
  });

  RunResult r;
  r.layout = fd ? "CAN FD, 8 sets of 4 x 16 bit per 64-byte frame" : "classic CAN, 1 set of 4 x 16 bit per 8-byte frame";
  r.rate = rate;
  r.seconds = seconds;
  r.sent = total;
  std::vector<double> latencies;
  const double cpu0 = ThreadCpuSeconds();
  const auto start = std::chrono::steady_clock::now();
  std::uint64_t next = 0;
  for (int empty = 0; r.received + acquisition.stats().lost_sample_sets < total && empty < 5;) {
    const daq::AcquiredBlock block = acquisition.Read(std::chrono::milliseconds(200));
    if (block.empty()) {
      ++empty;
      continue;
    }
    empty = 0;
    latencies.push_back((daq::MonotonicNs() - block.time_ns.back()) * 1e-6);
    for (std::size_t k = 0; k < block.size(); ++k)
      for (int c = 0; c < 4; ++c)
        if (block.counts[c][k] != Expected(block.first_index + k, c)) ++r.wrong_values;
    r.received += block.size();
    next = block.first_index + block.size();
  }
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  r.receiver_cpu = (ThreadCpuSeconds() - cpu0) / wall;
  sender_thread.join();
  r.sender_cpu = sender_cpu;
  const daq::AcquisitionStats& s = acquisition.stats();
  r.lost = s.lost_sample_sets + (total - std::min(total, next));  // sets never seen at the end count as lost
  r.corrupt = s.corrupt_frames;
  r.drops = s.receiver_drops;
  if (!latencies.empty()) {
    std::nth_element(latencies.begin(), latencies.begin() + latencies.size() / 2, latencies.end());
    r.block_latency_ms = latencies[latencies.size() / 2];
  }
  if (sender_failed) throw std::runtime_error("the sender failed");
  return r;
}

struct BenchAcquisition {
  double seconds = 5.0;
  double fd_rate = 50000.0;
  std::string json_path;

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
      const RunResult r = RunStream(is_fd, rate, seconds);
      const bool ok = r.lost == 0 && r.wrong_values == 0 && r.corrupt == 0;
      all_ok &= ok && r.receiver_cpu < 0.10;
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
    report["all_targets_met"] = all_ok;
    if (!json_path.empty()) {
      WriteTextOutput(json_path, report.dump(1) + "\n");
    }
  }
};

}  // namespace

void RegisterBenchAcquisition(CLI::App& bench) {
  auto b = std::make_shared<BenchAcquisition>();
  CLI::App* sub = bench.add_subcommand(
      "acquisition", "CAN acquisition over UDP on loopback: lost samples and receiver CPU at 4 x 50 kHz (CAN FD) "
                     "and at the classic layout's bus limit; the bus arithmetic");
  sub->add_option("--seconds", b->seconds, "Length of each stream.")->check(Between(0.5, 600.0))->capture_default_str();
  sub->add_option("--fd-rate", b->fd_rate, "Sample sets per second of the CAN FD stream.")
      ->check(Between(100.0, 400000.0))
      ->capture_default_str();
  sub->add_option("--json", b->json_path, "Also write the figures as JSON.");
  sub->callback([b] { b->Run(); });
}

}  // namespace strut::tools
