#include "strut/study/acquisition.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <exception>
#include <thread>
#include <vector>

#include "strut/daq/can_acquisition.h"
#include "strut/study/cpu_time.h"
#include "strut/study/statistics.h"

namespace strut::study {
namespace {

//! The count channel c of sample set i carries: a different sine per channel, deterministic.
std::int16_t Expected(std::uint64_t i, int c) {
  return static_cast<std::int16_t>(std::lround(20000.0 * std::sin(0.001 * static_cast<double>(i) * (c + 1) + c)));
}

//! Plays the module in real time: sets due by the clock, flushed every millisecond. Returns the
//! sender's CPU as a share of one core.
double Send(const daq::CanAcquisitionOptions& options, std::uint16_t port, double rate, std::uint64_t total) {
  daq::CanAcquisitionSender sender(daq::UdpCanTransport::Connect("127.0.0.1", port), options.layout,
                                   static_cast<int>(rate / 10));
  sender.flush_sets = ~std::size_t{0};  // flushed by the 1 ms ticks below
  const double cpu0 = ThreadSeconds();
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
  return (ThreadSeconds() - cpu0) / std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

CanStreamRun RunCanStream(bool fd, double rate, double seconds) {
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
  std::exception_ptr sender_error;  // rethrown here once the thread has joined
  std::thread sender_thread([&] {
    try {
      sender_cpu = Send(options, port, rate, total);
    } catch (...) {
      sender_error = std::current_exception();
    }
  });

  CanStreamRun r;
  r.layout = fd ? "CAN FD, 8 sets of 4 x 16 bit per 64-byte frame" : "classic CAN, 1 set of 4 x 16 bit per 8-byte frame";
  r.rate = rate;
  r.seconds = seconds;
  r.sent = total;
  std::vector<double> latencies;
  const double cpu0 = ThreadSeconds();
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
  r.receiver_cpu = (ThreadSeconds() - cpu0) / wall;
  sender_thread.join();
  if (sender_error) std::rethrow_exception(sender_error);
  r.sender_cpu = sender_cpu;
  const daq::AcquisitionStats& s = acquisition.stats();
  r.lost = s.lost_sample_sets + (total - std::min(total, next));  // sets never seen at the end count as lost
  r.corrupt = s.corrupt_frames;
  r.drops = s.receiver_drops;
  if (!latencies.empty()) r.block_latency_ms = Median(latencies);
  return r;
}

}  // namespace strut::study
