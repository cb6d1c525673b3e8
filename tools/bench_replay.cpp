// strut bench replay: how fast a recorded session replays as fast as possible, in sample sets per
// CPU second: the replay alone, replay into the recorder (what `strut replay -o` does) and replay
// sent as CAN frames over UDP on loopback (`strut replay --to`), docs/replay.md "Figures".
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <time.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>

#include "bench_support.h"
#include "commands.h"
#include "option_checks.h"
#include "output_files.h"
#include "strut/daq/replay.h"

namespace strut::tools {
namespace {

struct BenchReplay {
  double seconds = 20.0;
  double rate = 50000.0;
  std::string dir;
  std::string json_path;

  // One periodic experiment as strut's recorder stores a CAN stream: stroke, force and pressure
  // with their counts and calibration, sequence and status.
  daq::Session Session() const {
    daq::Session s;
    s.source_path = "bench session (in memory)";
    s.created_utc = daq::UtcNowIso8601();
    s.damper_serial = "BENCH-1";
    s.rig = "bench";
    daq::Experiment e;
    e.label = "a";
    e.sample_rate = rate;
    e.frequency = 1.0;
    e.amplitude = 0.05;
    e.static_position = 0.1;
    e.periods = std::lround(seconds);
    const auto n = static_cast<std::size_t>(std::llround(e.periods * rate));
    const daq::Calibration cal[] = {daq::Calibration::FromRange16(-0.01, 0.3), daq::Calibration::FromRange16(-6e4, 6e4),
                                    daq::Calibration::FromRange16(-1e5, 2e7)};
    const char* names[] = {"stroke", "force", "pressure"};
    const char* units[] = {"m", "N", "Pa"};
    daq::MetadataGroup calibration{"a", {}, {}};
    for (int c = 0; c < 3; ++c) {
      daq::Channel si{names[c], units[c], c == 2 ? "gauge" : "", std::vector<double>(n)};
      daq::Channel counts{std::string(names[c]) + "_counts", "1", "", std::vector<double>(n)};
      for (std::size_t i = 0; i < n; ++i) {
        const auto k = static_cast<std::int32_t>(std::lround(30000 * std::sin(2 * M_PI * i / rate + c)));
        counts.samples[i] = k;
        si.samples[i] = cal[c].ToSi(k);
      }
      calibration.groups.push_back({names[c],
                                    {{"gain", cal[c].gain},
                                     {"offset", cal[c].offset},
                                     {"range_min", cal[c].range_min},
                                     {"range_max", cal[c].range_max},
                                     {"counts_channel", counts.name}},
                                    {}});
      e.channels.push_back(std::move(si));
      e.channels.push_back(std::move(counts));
    }
    daq::Channel sequence{"sequence", "1", "", std::vector<double>(n)}, status{"status", "1", "", std::vector<double>(n)};
    e.time.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      e.time[i] = static_cast<double>(i) / rate;
      sequence.samples[i] = static_cast<double>(1000 + i);
    }
    e.channels.push_back(std::move(sequence));
    e.channels.push_back(std::move(status));
    s.experiments.push_back(std::move(e));
    s.metadata.push_back({"recording", {{"software_version", std::string("bench")}}, {{"calibration", {}, {calibration}}}});
    return s;
  }

  void Run() const {
    namespace fs = std::filesystem;
    const fs::path folder = dir.empty() ? fs::temp_directory_path() : fs::path(dir);
    if (!fs::is_directory(folder)) throw std::invalid_argument(fmt::format("--dir {}: not a directory", folder.string()));
    const std::string out = (folder / fmt::format("strut-bench-replay-{}.h5", ::getpid())).string();
    const daq::Session session = Session();
    const double sets = static_cast<double>(session.experiments.front().sample_count());

    struct Figure {
      std::string name;
      double wall = 0.0, cpu = 0.0;
    };
    std::vector<Figure> figures;
    {
      daq::ReplayAcquisition replay(session);
      const double cpu0 = ThreadSeconds();
      const daq::ReplayFigures f = daq::PlayReplay(replay, nullptr);
      figures.push_back({"replay alone (ReplayAcquisition::Read)", f.wall_s, ThreadSeconds() - cpu0});
    }
    {
      daq::ReplayAcquisition replay(session);
      daq::RecorderOptions options;
      options.force = true;
      options.queue_full_timeout = std::chrono::milliseconds(60000);
      const double cpu0 = ProcessSeconds();
      const auto t0 = MonotonicSeconds();
      daq::Recorder recorder = daq::Recorder::Open(out, daq::ReplayMetadata(session), options);
      daq::PlayReplay(replay, &recorder);
      recorder.Close();
      figures.push_back({"replay into the recorder, session written", MonotonicSeconds() - t0, ProcessSeconds() - cpu0});
      fs::remove(out);
    }
    {
      daq::ReplayAcquisition replay(session);  // as fast as possible, in the frames of a real-time stream
      const daq::CanAcquisitionOptions can = daq::ReplayCanOptions(daq::ReplayAcquisition(session, {1.0, 0}));
      // A receiving socket nobody reads: the kernel drops what overflows, the sender never waits.
      auto sink = daq::UdpCanTransport::Listen("127.0.0.1", 0, 1 << 16);
      const double cpu0 = ThreadSeconds();
      const daq::ReplayFigures f =
          daq::SendReplay(replay, daq::UdpCanTransport::Connect("127.0.0.1", sink->local_port()), can);
      figures.push_back({fmt::format("replay sent over UDP ({})", can.layout.fd ? "CAN FD" : "classic CAN"), f.wall_s,
                         ThreadSeconds() - cpu0});
    }

    std::cout << fmt::format("replay bench: {:.0f} sample sets (3 channels with counts, sequence, status; {:g} Hz, {:g} s "
                             "recorded), as fast as possible\n\n",
                             sets, rate, sets / rate);
    std::cout << fmt::format("{:<46} {:>8} {:>8} {:>16} {:>14}\n", "", "wall s", "CPU s", "sets per CPU s",
                             "x real time");
    nlohmann::json json;
    json["sample_sets"] = sets;
    json["rate_hz"] = rate;
    for (const Figure& f : figures) {
      std::cout << fmt::format("{:<46} {:>8.3f} {:>8.3f} {:>16.3g} {:>14.0f}\n", f.name, f.wall, f.cpu, sets / f.cpu,
                               sets / rate / f.wall);
      json["figures"].push_back({{"name", f.name},
                                 {"wall_s", f.wall},
                                 {"cpu_s", f.cpu},
                                 {"sets_per_cpu_s", sets / f.cpu},
                                 {"times_real_time", sets / rate / f.wall}});
    }
    if (!json_path.empty()) {
      WriteTextOutput(json_path, json.dump(1) + "\n");
    }
  }

  static double MonotonicSeconds() { return static_cast<double>(daq::MonotonicNs()) / 1e9; }
};

}  // namespace

void RegisterBenchReplay(CLI::App& bench) {
  auto command = std::make_shared<BenchReplay>();
  CLI::App* sub = bench.add_subcommand(
      "replay", "Replay as fast as possible: sample sets per CPU second alone, into the recorder and sent over UDP");
  sub->add_option("--seconds", command->seconds, "Recorded seconds (whole periods of 1 Hz).")
      ->check(Between(1.0, 3600.0))
      ->capture_default_str();
  sub->add_option("--rate", command->rate, "Sample rate, Hz.")->check(Between(100.0, 1e6))->capture_default_str();
  sub->add_option("--dir", command->dir, "Directory of the recording (default: the temp directory).");
  sub->add_option("--json", command->json_path, "Also write the figures as JSON.");
  sub->callback([command] { command->Run(); });
}

}  // namespace strut::tools
