// The monitor's server against a plain HTTP client on a socket: when the run ends, a page that is
// connected gets everything the feed was last handed (the run's last event, a pause) before its
// stream ends, and the stream ends cleanly rather than being cut (docs/monitor.md).
#include <gtest/gtest.h>
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <chrono>
#include <string>
#include <thread>

#include "strut/monitor/feed.h"
#include "strut/monitor/server.h"
#include "test_support.h"

namespace strut::monitor {
namespace {

struct StreamRead {
  std::string text;
  bool ended = false;  // the server closed the stream (not our timeout)
};

// GET /events and read until the server closes the connection or `timeout` passes.
StreamRead ReadEventStream(int port, std::chrono::seconds timeout) {
  StreamRead r;
  const int s = test::ConnectToLoopback(port);
  if (s < 0) return r;
  timeval tv{static_cast<time_t>(timeout.count()), 0};
  setsockopt(s, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  const std::string request = "GET /events HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n";
  if (send(s, request.data(), request.size(), 0) == static_cast<ssize_t>(request.size())) {
    char buffer[4096];
    for (;;) {
      const ssize_t n = recv(s, buffer, sizeof buffer, 0);
      if (n == 0) r.ended = true;
      if (n <= 0) break;
      r.text.append(buffer, static_cast<std::size_t>(n));
    }
  }
  close(s);
  return r;
}

TEST(MonitorServer, APageConnectedWhenTheRunEndsGetsItsLastEventBeforeTheStreamEnds) {
  MonitorFeed feed({"stroke", "force"}, 200.0, 1.0);
  MonitorServer server(feed, MonitorSetup{}, MonitorOptions{"127.0.0.1", 0, false});
  StreamRead page;
  std::thread reader([&] { page = ReadEventStream(server.port(), std::chrono::seconds(20)); });
  for (int i = 0; i < 500 && server.clients() == 0; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  ASSERT_EQ(server.clients(), 1);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // the snapshot is out; the hub is between takes

  // The run's end: its last event, handed over, and the server stopped at once, well inside the
  // hub's period, so only the drain on Stop can bring the event to the page.
  feed.Event("progress", "experiment q complete");
  feed.Event("paused", "paused after experiment q: requested from the page");
  feed.Flush();
  const auto stop_started = std::chrono::steady_clock::now();
  server.Stop();
  const double stop_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - stop_started).count();
  reader.join();

  EXPECT_TRUE(page.ended) << "the stream was not closed by the server";
  EXPECT_NE(page.text.find("event: snapshot"), std::string::npos) << page.text;
  EXPECT_NE(page.text.find("experiment q complete"), std::string::npos) << page.text;
  EXPECT_NE(page.text.find("paused after experiment q"), std::string::npos) << page.text;
  EXPECT_LT(stop_s, 2.0);  // the page read everything: Stop did not wait out its drain limit
  server.Stop();           // idempotent
}

TEST(MonitorServer, APageThatStopsReadingDoesNotHoldTheRunsEndBeyondTheDrainLimit) {
  MonitorFeed feed({"stroke"}, 200.0, 1.0);
  MonitorServer server(feed, MonitorSetup{}, MonitorOptions{"127.0.0.1", 0, false});
  // A client that connects, asks for the stream and never reads a byte.
  // Its receive buffer made small before it connects (the window is set then).
  const int s = socket(AF_INET, SOCK_STREAM, 0);
  int small = 1024;
  setsockopt(s, SOL_SOCKET, SO_RCVBUF, &small, sizeof small);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = htons(static_cast<std::uint16_t>(server.port()));
  ASSERT_EQ(connect(s, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
  const std::string request = "GET /events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n";
  ASSERT_EQ(send(s, request.data(), request.size(), 0), static_cast<ssize_t>(request.size()));
  for (int i = 0; i < 500 && server.clients() == 0; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  // Far more than the socket buffers hold, so the server's writes to this page block.
  daq::AcquiredBlock block;
  for (int i = 0; i < 20000; ++i) {
    block.time_ns.push_back(1'000'000'000LL + i * 5'000'000LL);
  }
  block.values.assign(1, std::vector<double>(20000, 0.123456789));
  for (int k = 0; k < 20; ++k) {
    feed.Block(block);
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  feed.Event("paused", "paused");
  feed.Flush();
  const auto stop_started = std::chrono::steady_clock::now();
  server.Stop();
  const double stop_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - stop_started).count();
  close(s);
  EXPECT_LT(stop_s, 6.0);  // the drain limit, then a blocked write's timeout: 2 s each
}

}  // namespace
}  // namespace strut::monitor
