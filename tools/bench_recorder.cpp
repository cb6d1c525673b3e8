// strut bench recorder: the streaming recorder's throughput as a ratio to raw sequential writes of
// the same bytes on the same disk, and its CPU per sample (docs/recording.md "Figures").
#include <fcntl.h>
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <thread>

#include "bench_support.h"
#include "commands.h"
#include "output_files.h"
#include "strut/daq/recorder.h"
#include "option_checks.h"

namespace strut::tools {
namespace {

using Clock = std::chrono::steady_clock;

double Seconds(Clock::time_point since) { return std::chrono::duration<double>(Clock::now() - since).count(); }

struct Figure {
  std::string name;
  double wall = 0.0;
  double cpu = 0.0;
  double bytes = 0.0;
};

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

struct BenchRecorder {
  double seconds = 20.0;
  double rate = 50000.0;
  int channels = 4;
  double block_ms = 10.0;
  int repeats = 3;
  std::string dir;
  std::string json_path;

  // Blocks as an acquisition would hand them over: SI values, raw counts, sequence and status.
  std::vector<daq::SampleBlock> Blocks() const {
    const auto total = static_cast<std::size_t>(std::llround(seconds * rate));
    const auto per_block = std::max<std::size_t>(1, static_cast<std::size_t>(std::llround(block_ms * 1e-3 * rate)));
    const daq::Calibration calibration{1e-5, 0.0, -0.327, 0.327};
    std::vector<daq::SampleBlock> blocks;
    const std::int64_t start = 1'000'000'000;
    for (std::size_t first = 0; first < total; first += per_block) {
      const std::size_t n = std::min(per_block, total - first);
      daq::SampleBlock b;
      b.values.assign(channels, std::vector<double>(n));
      b.counts.assign(channels, std::vector<std::int32_t>(n));
      for (std::size_t i = 0; i < n; ++i) {
        const std::size_t k = first + i;
        b.monotonic_ns.push_back(start + static_cast<std::int64_t>(std::llround(k * 1e9 / rate)));
        for (int c = 0; c < channels; ++c) {
          const auto counts = static_cast<std::int32_t>(std::lround(20000 * std::sin(0.001 * k + c)));
          b.counts[c][i] = counts;
          b.values[c][i] = calibration.ToSi(counts);
        }
        b.sequence.push_back(k);
        b.status.push_back(0);
      }
      blocks.push_back(std::move(b));
    }
    return blocks;
  }

  daq::ExperimentDescriptor Descriptor() const {
    daq::ExperimentDescriptor d;
    d.header.label = "bench";
    d.header.kind = daq::ExperimentKind::kStatic;
    d.header.sample_rate = rate;
    const char* names[] = {"stroke", "force", "pressure"};
    const char* units[] = {"m", "N", "Pa"};
    for (int c = 0; c < channels; ++c) {
      daq::Channel channel;
      channel.name = c < 3 ? names[c] : fmt::format("aux{}", c - 2);
      channel.units = c < 3 ? units[c] : "V";
      if (channel.name == "pressure") channel.reference = "gauge";
      d.raw.push_back({channel.name, {1e-5, 0.0, -0.327, 0.327}});
      d.header.channels.push_back(std::move(channel));
    }
    d.sequence = d.status = true;
    return d;
  }

  // Writes `bytes` in 1 MiB pieces with write(2), fdatasync every `sync` (0: only at the end).
  Figure RawWrite(const std::string& path, std::uint64_t bytes, std::chrono::milliseconds sync) const {
    std::vector<char> buffer(1 << 20, 'x');
    const double cpu0 = ProcessSeconds();
    const auto t0 = Clock::now();
    const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0) throw std::runtime_error(fmt::format("{}: cannot create: {}", path, std::strerror(errno)));
    auto last_sync = Clock::now();
    for (std::uint64_t done = 0; done < bytes;) {
      const std::size_t n = std::min<std::uint64_t>(buffer.size(), bytes - done);
      const ssize_t w = ::write(fd, buffer.data(), n);
      if (w <= 0) {
        ::close(fd);
        throw std::runtime_error(fmt::format("{}: cannot write: {}", path, std::strerror(errno)));
      }
      done += static_cast<std::uint64_t>(w);
      if (sync.count() > 0 && Clock::now() - last_sync >= sync) {
        ::fdatasync(fd);
        last_sync = Clock::now();
      }
    }
    ::fdatasync(fd);
    ::close(fd);
    Figure f{sync.count() > 0 ? fmt::format("raw write(2), fdatasync every {} ms", sync.count())
                              : "raw write(2), one fdatasync at the end",
             Seconds(t0), ProcessSeconds() - cpu0, static_cast<double>(bytes)};
    std::filesystem::remove(path);
    return f;
  }

  void Run() const {
    namespace fs = std::filesystem;
    const fs::path folder = dir.empty() ? fs::temp_directory_path() : fs::path(dir);
    if (!fs::is_directory(folder)) throw std::invalid_argument(fmt::format("--dir {}: not a directory", folder.string()));
    const std::string session = (folder / fmt::format("strut-bench-recorder-{}.h5", ::getpid())).string();
    const std::vector<daq::SampleBlock> blocks = Blocks();
    const daq::ExperimentDescriptor descriptor = Descriptor();
    std::size_t samples = 0;
    for (const auto& b : blocks) samples += b.size();

    daq::RecorderOptions options;
    options.force = true;
    options.queue_full_timeout = std::chrono::milliseconds(60000);  // a throughput run: the producer may wait
    std::vector<double> stream_wall, stream_cpu, close_wall, close_cpu;
    std::uint64_t journal_bytes = 0;
    double session_bytes = 0.0;
    daq::RecorderStats last;
    for (int r = 0; r < repeats; ++r) {
      const double cpu0 = ProcessSeconds();
      const auto t0 = Clock::now();
      daq::Recorder recorder = daq::Recorder::Open(session, {"BENCH-1", "bench", "", "", "", {}, "damper", {}}, options);
      recorder.BeginExperiment(descriptor);
      for (const auto& b : blocks) recorder.Append(b);
      recorder.EndExperiment(daq::EndStatus::kComplete);
      // Streaming ends when the last block is durable: Close drains and syncs before converting,
      // so the two phases are timed through the journal's size on disk.
      while (recorder.stats().bytes_written < recorder.stats().bytes_handed) std::this_thread::sleep_for(std::chrono::microseconds(200));
      const double cpu1 = ProcessSeconds();
      const auto t1 = Clock::now();
      last = recorder.stats();
      journal_bytes = fs::file_size(recorder.journal_path());
      recorder.Close();
      stream_wall.push_back(std::chrono::duration<double>(t1 - t0).count());
      stream_cpu.push_back(cpu1 - cpu0);
      close_wall.push_back(Seconds(t1));
      close_cpu.push_back(ProcessSeconds() - cpu1);
      session_bytes = static_cast<double>(fs::file_size(session));
      fs::remove(session);
    }
    std::vector<Figure> raw_synced, raw_once;
    for (int r = 0; r < repeats; ++r) {
      raw_synced.push_back(RawWrite(session + ".raw", journal_bytes, options.sync_interval));
      raw_once.push_back(RawWrite(session + ".raw", journal_bytes, std::chrono::milliseconds(0)));
    }
    auto median = [](const std::vector<Figure>& figures) {
      std::vector<double> wall, cpu;
      for (const auto& f : figures) {
        wall.push_back(f.wall);
        cpu.push_back(f.cpu);
      }
      Figure f = figures.front();
      f.wall = Median(wall);
      f.cpu = Median(cpu);
      return f;
    };
    const Figure synced = median(raw_synced), once = median(raw_once);
    const double jb = static_cast<double>(journal_bytes);
    const Figure stream{"recorder: Append .. journal written", Median(stream_wall), Median(stream_cpu), jb};
    const Figure close{"recorder: Close (journal -> HDF5 session)", Median(close_wall), Median(close_cpu), jb};
    const Figure total{"recorder: total", stream.wall + close.wall, stream.cpu + close.cpu, jb};

    std::cout << fmt::format(
        "recorder bench: {} samples ({} channels + raw counts + sequence + status, {:g} Hz, {:g} s of data, blocks of "
        "{:g} ms), journal {:.1f} MB, session {:.1f} MB (gzip 4), in {}; medians of {}\n\n",
        samples, channels, rate, seconds, block_ms, jb / 1e6, session_bytes / 1e6, folder.string(), repeats);
    std::cout << fmt::format("{:<44} {:>8} {:>9} {:>13} {:>8} {:>14}\n", "", "wall s", "MB/s", "ratio to raw",
                             "CPU s", "CPU us/sample");
    for (const Figure* f : {&synced, &once, &stream, &close, &total}) {
      const double ratio = (f->bytes / f->wall) / (synced.bytes / synced.wall);
      std::cout << fmt::format("{:<44} {:>8.3f} {:>9.1f} {:>13.2f} {:>8.3f} {:>14.3f}\n", f->name, f->wall,
                               f->bytes / f->wall / 1e6, ratio, f->cpu, f->cpu / samples * 1e6);
    }
    const double core_share = stream.cpu / samples * rate;
    std::cout << fmt::format(
        "\nstreaming at {:g} Hz in real time would take {:.1f} % of one core (producer + writer thread); syncs {}, "
        "longest wait for a sync {:.0f} ms, queue high-water {:.1f} MB\n",
        rate, 100 * core_share, last.syncs, 1e3 * last.longest_sync_gap_s, last.max_queue_bytes / 1e6);
    if (!json_path.empty()) {
      nlohmann::json out;
      out["samples"] = samples;
      out["rate_hz"] = rate;
      out["channels"] = channels;
      out["journal_bytes"] = journal_bytes;
      out["session_bytes"] = session_bytes;
      for (const Figure* f : {&synced, &once, &stream, &close, &total}) {
        out["figures"].push_back({{"name", f->name},
                                  {"wall_s", f->wall},
                                  {"cpu_s", f->cpu},
                                  {"mb_per_s", f->bytes / f->wall / 1e6},
                                  {"ratio_to_raw", (f->bytes / f->wall) / (synced.bytes / synced.wall)},
                                  {"cpu_us_per_sample", f->cpu / samples * 1e6}});
      }
      out["core_share_at_rate"] = core_share;
      WriteTextOutput(json_path, out.dump(1) + "\n");
    }
  }
};

}  // namespace

void RegisterBenchRecorder(CLI::App& bench) {
  auto command = std::make_shared<BenchRecorder>();
  CLI::App* sub = bench.add_subcommand(
      "recorder", "Streaming recorder: throughput as a ratio to raw sequential writes, CPU per sample");
  sub->add_option("--seconds", command->seconds, "Seconds of data.")->check(Between(0.01, 3600.0))->capture_default_str();
  sub->add_option("--rate", command->rate, "Sample rate, Hz.")->check(Between(1.0, 1e7))->capture_default_str();
  sub->add_option("--channels", command->channels, "SI channels (each with raw counts).")
      ->check(Between(3, 64))
      ->capture_default_str();
  sub->add_option("--block-ms", command->block_ms, "Block length handed over per Append, ms.")
      ->check(Between(0.01, 10000.0))
      ->capture_default_str();
  sub->add_option("--repeats", command->repeats, "Runs of each (medians are printed).")->check(Between(1, 100))->capture_default_str();
  sub->add_option("--dir", command->dir, "Directory on the disk to measure (default: the temp directory).");
  sub->add_option("--json", command->json_path, "Also write the figures as JSON.");
  sub->callback([command] { command->Run(); });
}

}  // namespace strut::tools
