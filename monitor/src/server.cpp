#include "strut/monitor/server.h"

#include <fmt/format.h>
#include <httplib.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <map>
#include <stdexcept>
#include <thread>

namespace strut::monitor {

namespace {

using nlohmann::json;

// Points a page gets when it connects: the traces' window and the loops of the experiment.
constexpr std::size_t kHistoryPoints = 20000;
// Updates kept for pages a little behind; one further behind gets a fresh snapshot.
constexpr std::size_t kKeptUpdates = 50;
constexpr auto kHubPeriod = std::chrono::milliseconds(100);
// How long Stop waits for the connected pages to get the last updates.
constexpr auto kDrainTimeout = std::chrono::seconds(2);

json ToJson(const rig::Progress& p) {
  json j{{"experiment", p.experiment},
         {"index", p.index},
         {"total", p.total},
         {"phase", std::string(rig::ToString(p.phase))},
         {"cycles", p.cycles},
         {"periods_recorded", p.periods_recorded},
         {"periods_requested", p.periods_requested},
         {"steady_measure", p.steady_measure},
         {"margins",
          {{"stroke", p.margins.stroke}, {"force", p.margins.force}, {"pressure", p.margins.pressure},
           {"following", p.margins.following}}},
         {"stroke", p.stroke},
         {"force", p.force}};
  if (p.steady) {
    const rig::SteadyStateVerdict& v = *p.steady;
    j["steady"] = {{"cycles", v.cycles},   {"agreeing", v.agreeing},           {"measure", v.measure},
                   {"steady", v.steady},   {"timed_out", v.timed_out},         {"force", v.last_change.force},
                   {"stroke", v.last_change.stroke}, {"pressure", v.last_change.pressure}, {"drift", v.drift},
                   {"elapsed", v.elapsed}};
  }
  return j;
}

json ToJson(const MonitorEvent& e) { return {{"wall", e.wall}, {"kind", e.kind}, {"text", e.text}}; }

json SetupJson(const MonitorSetup& s, const MonitorFeed& feed, bool control) {
  json items = json::array();
  for (const rig::RunItem& i : s.items)
    items.push_back({{"label", i.label()},
                     {"frequency", i.entry.frequency},
                     {"amplitude", i.entry.amplitude},
                     {"static_position", i.entry.static_position}});
  const auto limit = [](const rig::ChannelLimit& l) {
    return l.enabled ? json{{"lower", l.lower}, {"upper", l.upper}} : json(nullptr);
  };
  const rig::SteadyStateTolerances& t = s.steady;
  return {{"title", s.title},
          {"channels", feed.channels()},
          {"speed", feed.speed()},
          {"items", items},
          {"limits", {{"stroke", limit(s.limits.stroke)}, {"force", limit(s.limits.force)}, {"pressure", limit(s.limits.pressure)}}},
          {"tolerances",
           {{"force", t.force}, {"stroke", t.stroke}, {"pressure", t.pressure}, {"drift", t.pressure_drift},
            {"drift_window", t.drift_window}, {"consecutive", t.consecutive}, {"time_limit", t.time_limit}}},
          {"control", control}};
}

bool Loopback(const std::string& address) {
  return address == "127.0.0.1" || address == "::1" || address.rfind("127.", 0) == 0 || address == "::ffff:127.0.0.1";
}

std::string Sse(const char* event, const json& data) { return fmt::format("event: {}\ndata: {}\n\n", event, data.dump()); }

}  // namespace

MonitorOptions ParseMonitorEndpoint(const std::string& text) {
  MonitorOptions o;
  if (text.empty()) return o;  // --monitor without a value: the defaults
  const auto colon = text.rfind(':');
  const std::string port = colon == std::string::npos ? text : text.substr(colon + 1);
  if (colon != std::string::npos) o.host = text.substr(0, colon);
  char* end = nullptr;
  const long p = std::strtol(port.c_str(), &end, 10);
  if (port.empty() || *end != '\0' || p < 0 || p > 65535 || o.host.empty())
    throw std::invalid_argument(fmt::format("--monitor '{}': expected HOST:PORT or PORT (0..65535)", text));
  o.port = static_cast<int>(p);
  return o;
}

struct MonitorServer::Impl {
  MonitorFeed& feed;
  MonitorSetup setup;
  MonitorOptions options;
  MonitorControls controls;
  httplib::Server http;
  int port = 0;
  std::thread listener, hub;
  std::atomic<int> clients{0};

  mutable std::mutex mutex;
  std::condition_variable changed;
  bool hub_done = false;  // the hub's last take is published
  bool closing = false;   // Stop has begun: the hub takes the feed once more, the pages get the rest
  bool stopping = false;  // the streams end now
  std::uint64_t seq = 0;
  std::uint64_t next_client = 0;
  std::map<std::uint64_t, std::uint64_t> delivered;  // per connected page, the last seq written to it
  std::deque<std::pair<std::uint64_t, std::string>> updates;  // seq, SSE text
  std::deque<double> t;
  std::vector<std::deque<double>> values;
  std::optional<json> progress;
  json events = json::array();
  std::uint64_t dropped = 0;

  Impl(MonitorFeed& f, MonitorSetup s, MonitorOptions o, MonitorControls c)
      : feed(f), setup(std::move(s)), options(std::move(o)), controls(std::move(c)), values(f.channels().size()) {}

  json Snapshot() const {  // under mutex
    json v = json::array();
    for (const auto& c : values) v.push_back(std::vector<double>(c.begin(), c.end()));
    return {{"seq", seq},
            {"setup", SetupJson(setup, feed, options.control)},
            {"t", std::vector<double>(t.begin(), t.end())},
            {"v", v},
            {"progress", progress ? *progress : json(nullptr)},
            {"events", events},
            {"dropped", dropped}};
  }

  void Hub() {
    for (;;) {
      bool last;
      {
        std::unique_lock lock(mutex);
        changed.wait_for(lock, kHubPeriod, [this] { return closing; });
        last = closing;
      }
      Publish(feed.Take());
      if (last) return;
    }
  }

  void Publish(FeedBatch b) {
    if (b.empty()) return;
    json update{{"t", b.t}, {"v", b.values}, {"dropped", b.dropped}, {"now", feed.Elapsed()}};
    if (b.progress) update["progress"] = ToJson(*b.progress);
    json ev = json::array();
    for (const MonitorEvent& e : b.events) ev.push_back(ToJson(e));
    update["events"] = ev;
    std::lock_guard lock(mutex);
    update["seq"] = ++seq;
    t.insert(t.end(), b.t.begin(), b.t.end());
    for (std::size_t c = 0; c < values.size(); ++c) values[c].insert(values[c].end(), b.values[c].begin(), b.values[c].end());
    while (t.size() > kHistoryPoints) {
      t.pop_front();
      for (auto& c : values) c.pop_front();
    }
    if (b.progress) progress = update["progress"];
    for (const json& e : ev) events.push_back(e);
    dropped += b.dropped;
    updates.emplace_back(seq, Sse("update", update));
    while (updates.size() > kKeptUpdates) updates.pop_front();
    changed.notify_all();
  }

  // One page's stream: a snapshot first, then every update, a comment every second to keep the
  // connection (and the page's "connected" state) alive. When the server stops, the stream ends
  // once the page has everything the feed was last handed (a pause's event comes last).
  bool Stream(std::uint64_t client, std::uint64_t& sent, bool& started, httplib::DataSink& sink) {
    std::string out;
    std::uint64_t upto;
    {
      std::unique_lock lock(mutex);
      if (started) changed.wait_for(lock, std::chrono::seconds(1), [&] { return stopping || (closing && hub_done) || seq > sent; });
      if (stopping || (closing && started && sent >= seq && hub_done)) {
        sink.done();
        return false;
      }
      if (!started || (seq > sent && (updates.empty() || updates.front().first > sent + 1))) {
        out = Sse("snapshot", Snapshot());
        started = true;
      } else {
        for (const auto& [s, text] : updates)
          if (s > sent) out += text;
      }
      upto = sent = seq;
    }
    if (out.empty()) out = ": alive\n\n";
    if (!sink.write(out.data(), out.size())) return false;
    std::lock_guard lock(mutex);
    delivered[client] = upto;
    changed.notify_all();
    return true;
  }

  void Routes() {
    http.Get("/", [this](const httplib::Request&, httplib::Response& res) {
      res.set_content(MonitorPage(options.control), "text/html; charset=utf-8");
    });
    http.Get("/state", [this](const httplib::Request&, httplib::Response& res) {
      std::lock_guard lock(mutex);
      res.set_content(Snapshot().dump(), "application/json");
    });
    http.Get("/events", [this](const httplib::Request&, httplib::Response& res) {
      res.set_header("Cache-Control", "no-cache");
      auto sent = std::make_shared<std::uint64_t>(0);
      auto started = std::make_shared<bool>(false);
      std::uint64_t client;
      {
        std::lock_guard lock(mutex);
        client = next_client++;
        delivered[client] = 0;
      }
      ++clients;
      res.set_chunked_content_provider(
          "text/event-stream",
          [this, client, sent, started](std::size_t, httplib::DataSink& sink) {
            return Stream(client, *sent, *started, sink);
          },
          [this, client](bool) {
            --clients;
            std::lock_guard lock(mutex);
            delivered.erase(client);
            changed.notify_all();
          });
    });
    http.Post(R"(/control/(pause|stop))", [this](const httplib::Request& req, httplib::Response& res) {
      if (!options.control || !Loopback(req.remote_addr)) {
        res.status = 403;
        res.set_content(options.control ? "control from loopback only\n" : "control is off (--monitor-control)\n",
                        "text/plain");
        return;
      }
      const bool pause = req.matches[1] == "pause";
      spdlog::warn("monitor: {} requested from the page", pause ? "pause" : "stop");
      const auto& act = pause ? controls.pause : controls.stop;
      if (act) act();
      res.set_content(pause ? "pause requested\n" : "stop requested\n", "text/plain");
    });
  }
};

MonitorServer::MonitorServer(MonitorFeed& feed, MonitorSetup setup, MonitorOptions options, MonitorControls controls)
    : impl_(std::make_unique<Impl>(feed, std::move(setup), std::move(options), std::move(controls))) {
  Impl& m = *impl_;
  // A page that stops reading blocks its stream's write; Stop waits for that write at most this long.
  m.http.set_write_timeout(kDrainTimeout);
  m.Routes();
  m.port = m.options.port == 0 ? m.http.bind_to_any_port(m.options.host) : m.options.port;
  if (m.port <= 0 || (m.options.port != 0 && !m.http.bind_to_port(m.options.host, m.options.port)))
    throw std::runtime_error(fmt::format("monitor: cannot listen on {}:{} (taken, or not an address of this machine)",
                                         m.options.host, m.options.port));
  m.listener = std::thread([&m] { m.http.listen_after_bind(); });
  m.hub = std::thread([&m] { m.Hub(); });
}

MonitorServer::~MonitorServer() { Stop(); }

void MonitorServer::Stop() {
  Impl& m = *impl_;
  {
    std::lock_guard lock(m.mutex);
    if (m.stopping) return;
    m.closing = true;
  }
  m.changed.notify_all();
  if (m.hub.joinable()) m.hub.join();
  {
    std::unique_lock lock(m.mutex);
    m.hub_done = true;
    m.changed.notify_all();
    // A page that stopped reading must not hold the run's end: it gets kDrainTimeout.
    m.changed.wait_for(lock, kDrainTimeout, [&m] {
      return std::all_of(m.delivered.begin(), m.delivered.end(), [&m](const auto& d) { return d.second >= m.seq; });
    });
    m.stopping = true;
  }
  m.changed.notify_all();
  m.http.stop();
  if (m.listener.joinable()) m.listener.join();
}

int MonitorServer::port() const { return impl_->port; }
std::string MonitorServer::url() const { return fmt::format("http://{}:{}/", impl_->options.host, impl_->port); }
int MonitorServer::clients() const { return impl_->clients.load(); }
std::uint64_t MonitorServer::dropped() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->dropped;
}

}  // namespace strut::monitor
