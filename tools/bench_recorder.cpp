// strut bench recorder: the streaming recorder's throughput as a ratio to raw sequential writes of
// the same bytes on the same disk, and its CPU per sample (study::RunRecorderSpeed,
// docs/recording.md "Figures").
#include <fmt/format.h>

#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "option_checks.h"
#include "output_files.h"
#include "strut/study/recorder_speed.h"

namespace strut::tools {
namespace {

struct BenchRecorder {
  study::RecorderSpeedOptions options;
  std::string dir;
  std::string json_path;

  void Run() {
    namespace fs = std::filesystem;
    const fs::path folder = dir.empty() ? fs::temp_directory_path() : fs::path(dir);
    if (!fs::is_directory(folder)) throw std::invalid_argument(fmt::format("--dir {}: not a directory", folder.string()));
    options.folder = folder.string();
    const study::RecorderSpeedStudy s = study::RunRecorderSpeed(options);
    const double jb = static_cast<double>(s.journal_bytes);
    std::cout << fmt::format(
        "recorder bench: {} samples ({} channels + raw counts + sequence + status, {:g} Hz, {:g} s of data, blocks of "
        "{:g} ms), journal {:.1f} MB, session {:.1f} MB (gzip 4), in {}; medians of {}\n\n",
        s.samples, options.channels, options.rate, options.seconds, options.block_ms, jb / 1e6, s.session_bytes / 1e6,
        folder.string(), options.repeats);
    std::cout << fmt::format("{:<44} {:>8} {:>9} {:>13} {:>8} {:>14}\n", "", "wall s", "MB/s", "ratio to raw",
                             "CPU s", "CPU us/sample");
    const study::WriteFigure& synced = s.figures.front();
    const auto ratio = [&](const study::WriteFigure& f) { return (f.bytes / f.wall) / (synced.bytes / synced.wall); };
    for (const study::WriteFigure& f : s.figures)
      std::cout << fmt::format("{:<44} {:>8.3f} {:>9.1f} {:>13.2f} {:>8.3f} {:>14.3f}\n", f.name, f.wall,
                               f.bytes / f.wall / 1e6, ratio(f), f.cpu, f.cpu / s.samples * 1e6);
    std::cout << fmt::format(
        "\nstreaming at {:g} Hz in real time would take {:.1f} % of one core (producer + writer thread); syncs {}, "
        "longest wait for a sync {:.0f} ms, queue high-water {:.1f} MB\n",
        options.rate, 100 * s.core_share, s.last.syncs, 1e3 * s.last.longest_sync_gap_s, s.last.max_queue_bytes / 1e6);
    if (json_path.empty()) return;
    nlohmann::json out;
    out["samples"] = s.samples;
    out["rate_hz"] = options.rate;
    out["channels"] = options.channels;
    out["journal_bytes"] = s.journal_bytes;
    out["session_bytes"] = s.session_bytes;
    for (const study::WriteFigure& f : s.figures)
      out["figures"].push_back({{"name", f.name},
                                {"wall_s", f.wall},
                                {"cpu_s", f.cpu},
                                {"mb_per_s", f.bytes / f.wall / 1e6},
                                {"ratio_to_raw", ratio(f)},
                                {"cpu_us_per_sample", f.cpu / s.samples * 1e6}});
    out["core_share_at_rate"] = s.core_share;
    WriteJsonOutput(json_path, out);
  }
};

}  // namespace

void RegisterBenchRecorder(CLI::App& bench) {
  auto [sub, command] = AddCommand<BenchRecorder>(
      bench, "recorder", "Streaming recorder: throughput as a ratio to raw sequential writes, CPU per sample");
  sub->add_option("--seconds", command->options.seconds, "Seconds of data.")->check(Between(0.01, 3600.0))->capture_default_str();
  sub->add_option("--rate", command->options.rate, "Sample rate, Hz.")->check(Between(1.0, 1e7))->capture_default_str();
  sub->add_option("--channels", command->options.channels, "SI channels (each with raw counts).")
      ->check(Between(3, 64))
      ->capture_default_str();
  sub->add_option("--block-ms", command->options.block_ms, "Block length handed over per Append, ms.")
      ->check(Between(0.01, 10000.0))
      ->capture_default_str();
  sub->add_option("--repeats", command->options.repeats, "Runs of each (medians are printed).")->check(Between(1, 100))->capture_default_str();
  sub->add_option("--dir", command->dir, "Directory on the disk to measure (default: the temp directory).");
  sub->add_option("--json", command->json_path, "Also write the figures as JSON.");
}

}  // namespace strut::tools
