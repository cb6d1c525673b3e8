// strut replay: a recorded session played back through the acquisition interface as the rig's
// stream (docs/replay.md): recorded in-process through the recorder (-o), or sent as CAN frames
// to a transport (--to) where a CanAcquisition receives it; either way shown live on the monitor's
// page (--monitor, docs/monitor.md).
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <filesystem>
#include <iostream>
#include <optional>
#include <span>

#include "commands.h"
#include "option_checks.h"
#include "output_files.h"
#include "strut/daq/replay.h"
#include "strut/monitor/replay_view.h"
#include "strut/monitor/server.h"
#include "strut/rig/replay_steady_state.h"

namespace strut::tools {
namespace {

std::string SteadyText(const rig::SteadyStateOnReplay::Row& row) {
  if (!row.judged) return "-";
  return fmt::format("{} ({} cycles)", row.verdict.steady ? "yes" : "no", row.verdict.cycles);
}

struct ReplayCommand {
  std::string file, out, to, speed;
  bool force = false;
  int gzip = 4;
  std::string monitor_endpoint;  // --monitor [HOST:PORT]
  CLI::Option* monitor_option = nullptr;

  bool monitoring() const { return monitor_option != nullptr && monitor_option->count() > 0; }

  // --speed: a number > 0 or "max"; the default is as fast as possible in-process, the rig's own
  // pace (1) over a transport, where a receiver must keep up, and on the monitor, where a person
  // watches.
  double Speed() const {
    if (speed.empty()) return to.empty() && !monitoring() ? 0.0 : 1.0;
    if (speed == "max") {
      if (monitoring())
        throw std::invalid_argument("--speed max with --monitor: the page shows the replay as it plays; give a speed "
                                    "(1: the recorded pace)");
      return 0.0;
    }
    double value = NAN;
    std::size_t used = 0;
    try {
      value = std::stod(speed, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != speed.size() || !std::isfinite(value) || value <= 0.0) {
      throw std::invalid_argument(fmt::format(
          "--speed {}: give a number > 0 (recorded seconds per wall second) or 'max' (as fast as possible)", speed));
    }
    return value;
  }

  void Run() {
    daq::ReplayOptions options;
    options.speed = Speed();
    if (!to.empty() && !out.empty()) {
      throw std::invalid_argument(fmt::format(
          "-o {} with --to {}: the receiver at {} records what is sent; -o records an in-process replay", out, to, to));
    }
    if (!to.empty() && options.speed == 0.0) {
      throw std::invalid_argument(fmt::format("--speed max with --to {}: a CAN receiver checks the frames against its "
                                              "clock and would drop them; give a speed (1: the recorded pace)",
                                              to));
    }
    namespace fs = std::filesystem;
    std::error_code ec;
    if (!out.empty()) {
      CheckOutputPath("--out", out, {file}, force);
      if (fs::exists(out, ec) && !force)
        throw std::invalid_argument(fmt::format("--out {}: exists; choose another name or add --force to replace it", out));
    }
    auto replay = daq::ReplayAcquisition::Open(file, options);
    const std::string pace = options.pace();

    daq::ReplayFigures figures;
    rig::SteadyStateOnReplay steady;
    // With --monitor the page's observer runs the steady-state detector first, so what is printed
    // below is what the page showed.
    daq::ReplayObserver* observer = &steady;
    std::optional<monitor::ReplayMonitor> view;
    std::optional<monitor::MonitorServer> page;
    if (monitoring()) {
      view.emplace(*replay, &steady);
      page.emplace(view->feed(), monitor::ReplaySetup(*replay, fmt::format("replay of {} {}", file, pace)),
                   monitor::ParseMonitorEndpoint(monitor_endpoint));
      spdlog::info("monitor: {}", page->url());
      observer = &*view;
    }
    if (!to.empty()) {
      const daq::CanAcquisitionOptions can = daq::ReplayCanOptions(*replay);
      // What a receiver is configured with: the calibration travels only here.
      std::cout << fmt::format("replay {} -> {} {}: {} Hz (the receiver's rate: recorded rate x speed), {} frames, "
                               "module {}\n",
                               file, to, pace, can.sample_rate, can.layout.fd ? "CAN FD" : "classic CAN",
                               can.layout.module);
      for (const daq::ChannelDescriptor& c : can.channels)
        std::cout << fmt::format("  channel {:<10} [{}] = {} + {} x counts, range {} .. {}\n", c.name, c.unit,
                                 c.calibration.offset, c.calibration.gain, c.calibration.range_min,
                                 c.calibration.range_max);
      figures = daq::SendReplay(*replay, daq::OpenCanTransport(to, false, can.layout.fd), can, observer);
    } else {
      std::cout << fmt::format("replay {}{} {}\n", file, out.empty() ? "" : " -> " + out, pace);
      if (out.empty()) {
        figures = daq::PlayReplay(*replay, nullptr, observer);
      } else {
        daq::RecorderOptions recorder_options;
        recorder_options.force = force;
        recorder_options.write.gzip_level = gzip;
        daq::Recorder recorder = daq::Recorder::Open(out, daq::ReplayMetadata(replay->session()), recorder_options);
        figures = daq::PlayReplay(*replay, &recorder, observer);
        recorder.Close();
        daq::ReadSession(out);  // what was written passes the contract check
        spdlog::info("wrote {}", out);
      }
    }
    if (view) {
      view->Finish();
      page->Stop();  // after the pages have the session's last events: they show "disconnected"
    }
    std::cout << fmt::format("{:<10} {:<9} {:>9} {:>10}  {:<13}  {}\n", "label", "kind", "samples", "end", "counts",
                             "steady (replayed stream)");
    for (std::size_t k = 0; k < replay->experiments().size(); ++k) {
      const daq::ReplayedExperiment& x = replay->experiments()[k];
      std::size_t recorded = 0;
      for (bool r : x.recorded_counts) recorded += r ? 1 : 0;
      std::cout << fmt::format("{:<10} {:<9} {:>9} {:>10}  {:<13}  {}\n", x.header.label,
                               daq::ToString(x.header.kind), x.samples, daq::ToString(x.end),
                               recorded == x.recorded_counts.size() ? "recorded"
                               : recorded == 0                      ? "derived"
                                                                    : "some recorded",
                               k < steady.rows().size() ? SteadyText(steady.rows()[k]) : "-");
      // A session the matrix runner recorded keeps every cycle it saw, settling included
      // (/rig_run/LABEL): the detector re-run on those gives the runner's own verdict.
      const daq::MetadataGroup* run = replay->session().find_metadata("rig_run");
      if (const daq::MetadataGroup* g = run ? run->find_group(x.header.label) : nullptr) {
        const rig::SteadyStateVerdict v = rig::DetectSteadyState(rig::CyclesFromGroup(*g), rig::TolerancesFromGroup(*g));
        std::cout << fmt::format("{:<10} the runner's cycles (/rig_run/{}): steady {} ({} cycles{})\n", "",
                                 x.header.label, v.steady ? "yes" : "no", v.cycles,
                                 v.steady ? fmt::format(", from cycle {}", v.steady_at) : "");
      }
      if (!x.exact_time) {
        spdlog::warn("experiment '{}': its time axis is not on whole nanoseconds (sample rate {} Hz); a recording "
                     "of the replay reproduces it to within 0.5 ns, not bit for bit",
                     x.header.label, x.stream.sample_rate);
      }
    }
    std::cout << fmt::format("{} experiments, {} sample sets, {:.1f} s recorded, played in {:.2f} s\n",
                             figures.experiments, figures.sample_sets, figures.recorded_s, figures.wall_s);
  }
};

}  // namespace

void RegisterReplayCommand(CLI::App& app) {
  auto [sub, command] = AddCommand<ReplayCommand>(
      app, "replay",
      "Play a recorded session back through the acquisition interface as the rig's stream: recorded again "
      "(-o) or sent as CAN frames (--to), docs/replay.md");
  sub->add_option("session", command->file, "The session to play (HDF5).")->required()->check(CLI::ExistingFile);
  sub->add_option("--speed", command->speed,
                  "Recorded seconds per wall second (a number > 0), or max: as fast as possible. Default: max, "
                  "1 with --to or --monitor.");
  sub->add_option("--to", command->to,
                  "Send the stream as CAN frames to udp:HOST:PORT or can:IFACE instead of recording it here.");
  sub->add_option("-o,--out", command->out, "Record the replay into this session file (HDF5), as a rig run records.");
  sub->add_flag("--force", command->force, "Replace an existing file at the output path.");
  command->monitor_option =
      sub->add_option("--monitor", command->monitor_endpoint,
                      "Show the replay live on the monitor's web page at HOST:PORT (default 127.0.0.1:8080; port 0: "
                      "any free port, logged), as strut rig run --monitor shows a run: the session's experiments as "
                      "the matrix, its recorded limits and events (docs/monitor.md).")
          ->expected(0, 1);
  sub->add_option("--gzip", command->gzip, "Compression level 0..9 of the recording.")
      ->check(Between(0, 9))
      ->capture_default_str();
}

}  // namespace strut::tools
