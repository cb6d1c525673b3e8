// The live monitor's web server (docs/monitor.md): one page on a local HTTP server (cpp-httplib)
// that shows a rig run (or a replay) as it happens, fed through Server-Sent Events from a
// MonitorFeed. A hub thread takes the feed's batches every 100 ms and keeps what a page that
// connects later needs; each page's stream waits on the hub, never on the acquisition.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "strut/monitor/feed.h"
#include "strut/rig/safety.h"
#include "strut/rig/steady_state.h"

namespace strut::monitor {

//! What the page shows besides the stream: the run's plan, the limits drawn into the traces.
struct MonitorSetup {
  std::string title;                  //!< e.g. the session file and the rig
  std::vector<rig::RunItem> items;    //!< the experiments of the run, in order
  rig::SafetyConfig limits;           //!< channel limits drawn into the traces
  rig::SteadyStateTolerances steady;  //!< the steady-state test's thresholds
};

struct MonitorOptions {
  std::string host = "127.0.0.1";  //!< loopback unless asked
  int port = 8080;                 //!< 0: an ephemeral port (port() says which)
  //! Pause and stop buttons; they act only for requests from loopback.
  bool control = false;
};

//! What the buttons do (as Ctrl-C once and twice).
struct MonitorControls {
  std::function<void()> pause, stop;
};

//! "HOST:PORT" or "PORT" into host and port, "" the defaults (127.0.0.1:8080); throws
//! std::invalid_argument naming the text.
MonitorOptions ParseMonitorEndpoint(const std::string& text);

class MonitorServer {
 public:
  //! Binds at once (std::runtime_error naming the address when it cannot) and serves from a thread.
  MonitorServer(MonitorFeed& feed, MonitorSetup setup, MonitorOptions options, MonitorControls controls = {});
  ~MonitorServer();
  MonitorServer(const MonitorServer&) = delete;
  MonitorServer& operator=(const MonitorServer&) = delete;

  int port() const;
  std::string url() const;
  //! Pages connected to the event stream now.
  int clients() const;
  //! Points the producer dropped because the hub fell behind (MonitorFeed), so far.
  std::uint64_t dropped() const;
  //! Stops serving (pages show "disconnected"); idempotent.
  void Stop();

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

//! The page (HTML with uPlot and its script inline).
std::string MonitorPage(bool control);

}  // namespace strut::monitor
