// strut bench replay: how fast a recorded session replays as fast as possible, in sample sets per
// CPU second (study::MeasureReplay): the replay alone, replay into the recorder and replay sent as
// CAN frames over UDP on loopback, docs/replay.md "Figures".
#include <fmt/format.h>
#include <unistd.h>

#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "option_checks.h"
#include "output_files.h"
#include "strut/study/replay_speed.h"

namespace strut::tools {
namespace {

struct BenchReplay {
  double seconds = 20.0;
  double rate = 50000.0;
  std::string dir;
  std::string json_path;

  void Run() const {
    namespace fs = std::filesystem;
    const fs::path folder = dir.empty() ? fs::temp_directory_path() : fs::path(dir);
    if (!fs::is_directory(folder)) throw std::invalid_argument(fmt::format("--dir {}: not a directory", folder.string()));
    const std::string out = (folder / fmt::format("strut-bench-replay-{}.h5", ::getpid())).string();
    const daq::Session session = study::ReplayBenchSession(seconds, rate);
    const double sets = static_cast<double>(session.experiments.front().sample_count());
    const std::vector<study::ReplayFigure> figures = study::MeasureReplay(session, out);
    std::cout << fmt::format("replay bench: {:.0f} sample sets (3 channels with counts, sequence, status; {:g} Hz, {:g} s "
                             "recorded), as fast as possible\n\n",
                             sets, rate, sets / rate);
    std::cout << fmt::format("{:<46} {:>8} {:>8} {:>16} {:>14}\n", "", "wall s", "CPU s", "sets per CPU s",
                             "x real time");
    nlohmann::json json;
    json["sample_sets"] = sets;
    json["rate_hz"] = rate;
    for (const study::ReplayFigure& f : figures) {
      std::cout << fmt::format("{:<46} {:>8.3f} {:>8.3f} {:>16.3g} {:>14.0f}\n", f.name, f.wall, f.cpu, sets / f.cpu,
                               sets / rate / f.wall);
      json["figures"].push_back({{"name", f.name},
                                 {"wall_s", f.wall},
                                 {"cpu_s", f.cpu},
                                 {"sets_per_cpu_s", sets / f.cpu},
                                 {"times_real_time", sets / rate / f.wall}});
    }
    if (!json_path.empty()) {
      WriteJsonOutput(json_path, json);
    }
  }

};

}  // namespace

void RegisterBenchReplay(CLI::App& bench) {
  auto [sub, command] = AddCommand<BenchReplay>(
      bench, "replay",
      "Replay as fast as possible: sample sets per CPU second alone, into the recorder and sent over UDP");
  sub->add_option("--seconds", command->seconds, "Recorded seconds (whole periods of 1 Hz).")
      ->check(Between(1.0, 3600.0))
      ->capture_default_str();
  sub->add_option("--rate", command->rate, "Sample rate, Hz.")->check(Between(100.0, 1e6))->capture_default_str();
  sub->add_option("--dir", command->dir, "Directory of the recording (default: the temp directory).");
  sub->add_option("--json", command->json_path, "Also write the figures as JSON.");
}

}  // namespace strut::tools
