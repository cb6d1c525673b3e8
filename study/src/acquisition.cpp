#include "strut/study/acquisition.h"

#include <arpa/inet.h>
#include <fmt/format.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <exception>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "strut/daq/can_acquisition.h"
#include "strut/monitor/feed.h"
#include "strut/monitor/server.h"
#include "strut/study/cpu_time.h"
#include "strut/study/statistics.h"

namespace strut::study {
namespace {

//! The count channel c of sample set i carries: a different sine per channel, deterministic.
std::int16_t Expected(std::uint64_t i, int c) {
  return static_cast<std::int16_t>(std::lround(20000.0 * std::sin(0.001 * static_cast<double>(i) * (c + 1) + c)));
}

//! Plays the module in real time: sets due by the clock, flushed every millisecond. Returns the
//! sender's CPU seconds.
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
  return ThreadSeconds() - cpu0;
}

//! What one page read of the monitor's event stream.
struct PageRead {
  std::uint64_t bytes = 0, updates = 0;
  bool ended = false;  //!< the server ended the stream (not our timeout, not a refused connection)
};

//! One page: GET /events on the monitor's loopback port, read as fast as it comes until the server
//! ends the stream (a browser's EventSource does no more before it parses). Gives up after 30 s
//! without a byte.
PageRead ReadPage(int port) {
  PageRead r;
  const int s = socket(AF_INET, SOCK_STREAM, 0);
  if (s < 0) return r;
  timeval timeout{30, 0};
  setsockopt(s, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  const std::string request = "GET /events HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n";
  if (connect(s, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0 &&
      send(s, request.data(), request.size(), 0) == static_cast<ssize_t>(request.size())) {
    static constexpr std::string_view kUpdate = "event: update";
    std::string text;  // what was read and not yet searched, less than one marker's length kept
    std::vector<char> buffer(1 << 16);
    for (;;) {
      const ssize_t n = recv(s, buffer.data(), buffer.size(), 0);
      if (n == 0) r.ended = true;
      if (n <= 0) break;
      r.bytes += static_cast<std::uint64_t>(n);
      text.append(buffer.data(), static_cast<std::size_t>(n));
      std::size_t at = 0;
      for (std::size_t hit; (hit = text.find(kUpdate, at)) != std::string::npos; at = hit + kUpdate.size()) ++r.updates;
      text.erase(0, std::max(at, text.size() > kUpdate.size() ? text.size() - kUpdate.size() : 0));
    }
  }
  close(s);
  return r;
}

//! The monitor as a rig run serves it, with `pages` pages reading its event stream.
class MonitorUnderLoad {
 public:
  MonitorUnderLoad(const daq::CanAcquisitionOptions& options, int pages)
      : feed_(Names(options), options.sample_rate, 1.0),
        server_(feed_, monitor::MonitorSetup{"strut bench acquisition", {}, {}, {}},
                monitor::MonitorOptions{"127.0.0.1", 0, false}),
        reads_(static_cast<std::size_t>(pages)) {
    for (int p = 0; p < pages; ++p) pages_.emplace_back([this, p] { reads_[p] = ReadPage(server_.port()); });
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (server_.clients() < pages && std::chrono::steady_clock::now() < until)
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    if (server_.clients() < pages) {
      Stop();
      throw std::runtime_error(fmt::format("bench acquisition --pages: only {} of {} pages connected to the monitor "
                                           "at {} within 10 s",
                                           server_.clients(), pages, server_.url()));
    }
  }
  ~MonitorUnderLoad() { Stop(); }

  monitor::MonitorFeed& feed() { return feed_; }
  //! CPU seconds the pages' threads used so far, together.
  double PagesCpu() {
    double sum = 0.0;
    for (std::thread& t : pages_) sum += ThreadSeconds(t.native_handle());
    return sum;
  }
  //! Ends the streams (the pages read to their end) and fills the run's page figures.
  void Finish(CanStreamRun& r) {
    Stop();
    r.monitor_dropped = server_.dropped();
    r.page_updates_min = reads_.empty() ? 0 : ~std::uint64_t{0};
    for (const PageRead& p : reads_) {
      r.page_bytes += p.bytes;
      r.page_updates_min = std::min(r.page_updates_min, p.ended ? p.updates : 0);
    }
  }

 private:
  static std::vector<std::string> Names(const daq::CanAcquisitionOptions& options) {
    std::vector<std::string> names;
    for (const daq::ChannelDescriptor& c : options.channels) names.push_back(c.name);
    return names;
  }
  void Stop() {
    server_.Stop();
    for (std::thread& t : pages_)
      if (t.joinable()) t.join();
  }
  monitor::MonitorFeed feed_;
  monitor::MonitorServer server_;
  std::vector<PageRead> reads_;
  std::vector<std::thread> pages_;
};

}  // namespace

CanStreamRun RunCanStream(bool fd, double rate, double seconds, std::optional<int> pages) {
  daq::CanAcquisitionOptions options;
  options.layout.fd = fd;
  options.sample_rate = rate;
  for (const char* name : {"stroke", "force", "pressure", "temperature"})
    options.channels.push_back({name, "1", daq::Calibration::FromRange16(-1.0, 1.0)});
  auto receiver = daq::UdpCanTransport::Listen("127.0.0.1", 0);
  const std::uint16_t port = receiver->local_port();
  daq::CanAcquisition acquisition(std::move(receiver), options);
  std::optional<MonitorUnderLoad> monitor;
  if (pages) monitor.emplace(options, *pages);
  acquisition.Start();

  const std::uint64_t total = static_cast<std::uint64_t>(rate * seconds);
  const double process0 = ProcessSeconds(), pages0 = monitor ? monitor->PagesCpu() : 0.0;
  const auto window = std::chrono::steady_clock::now();
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
    if (monitor) monitor->feed().Block(block);  // as the rig runner's on_block: never waits
  }
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  r.receiver_cpu = (ThreadSeconds() - cpu0) / wall;
  sender_thread.join();
  const double pages1 = monitor ? monitor->PagesCpu() : 0.0;
  const double window_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - window).count();
  // The receiving process as it would be alone: the sender and the pages are other processes on a rig.
  r.process_cpu = (ProcessSeconds() - process0 - sender_cpu - (pages1 - pages0)) / window_s;
  if (sender_error) std::rethrow_exception(sender_error);
  r.sender_cpu = sender_cpu / window_s;
  if (monitor) {
    r.pages = pages;
    r.page_cpu = (pages1 - pages0) / window_s;
    monitor->Finish(r);
  }
  const daq::AcquisitionStats& s = acquisition.stats();
  r.lost = s.lost_sample_sets + (total - std::min(total, next));  // sets never seen at the end count as lost
  r.corrupt = s.corrupt_frames;
  r.drops = s.receiver_drops;
  if (!latencies.empty()) r.block_latency_ms = Median(latencies);
  return r;
}

MonitorLoad RunMonitorLoad(double rate, double seconds, int pages, int repeats) {
  MonitorLoad m;
  std::vector<double> receiver_without, receiver_with, process_without, process_with;
  for (int k = 0; k < repeats; ++k) {
    for (const int n : {0, pages}) {
      const CanStreamRun r = RunCanStream(true, rate, seconds, n);
      m.lost += r.lost;
      (n == 0 ? m.without_pages : m.with_pages).push_back(r);
      (n == 0 ? receiver_without : receiver_with).push_back(r.receiver_cpu);
      (n == 0 ? process_without : process_with).push_back(r.process_cpu);
    }
  }
  m.receiver_cpu_without = Median(receiver_without);
  m.receiver_cpu_with = Median(receiver_with);
  m.process_cpu_without = Median(process_without);
  m.process_cpu_with = Median(process_with);
  return m;
}

}  // namespace strut::study
