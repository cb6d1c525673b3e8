#include "strut/study/recorder_speed.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <thread>

#include "strut/study/cpu_time.h"
#include "strut/study/statistics.h"

namespace strut::study {
namespace {

using Clock = std::chrono::steady_clock;

double Seconds(Clock::time_point since) { return std::chrono::duration<double>(Clock::now() - since).count(); }

// Blocks as an acquisition would hand them over: SI values, raw counts, sequence and status.
std::vector<daq::SampleBlock> Blocks(const RecorderSpeedOptions& o) {
  const auto total = static_cast<std::size_t>(std::llround(o.seconds * o.rate));
  const auto per_block = std::max<std::size_t>(1, static_cast<std::size_t>(std::llround(o.block_ms * 1e-3 * o.rate)));
  const daq::Calibration calibration{1e-5, 0.0, -0.327, 0.327};
  std::vector<daq::SampleBlock> blocks;
  const std::int64_t start = 1'000'000'000;
  for (std::size_t first = 0; first < total; first += per_block) {
    const std::size_t n = std::min(per_block, total - first);
    daq::SampleBlock b;
    b.values.assign(o.channels, std::vector<double>(n));
    b.counts.assign(o.channels, std::vector<std::int32_t>(n));
    for (std::size_t i = 0; i < n; ++i) {
      const std::size_t k = first + i;
      b.monotonic_ns.push_back(start + static_cast<std::int64_t>(std::llround(k * 1e9 / o.rate)));
      for (int c = 0; c < o.channels; ++c) {
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

daq::ExperimentDescriptor Descriptor(const RecorderSpeedOptions& o) {
  daq::ExperimentDescriptor d;
  d.header.label = "bench";
  d.header.kind = daq::ExperimentKind::kStatic;
  d.header.sample_rate = o.rate;
  const char* names[] = {"stroke", "force", "pressure"};
  const char* units[] = {"m", "N", "Pa"};
  for (int c = 0; c < o.channels; ++c) {
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
WriteFigure RawWrite(const std::string& path, std::uint64_t bytes, std::chrono::milliseconds sync) {
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
  WriteFigure f{sync.count() > 0 ? fmt::format("raw write(2), fdatasync every {} ms", sync.count())
                                 : "raw write(2), one fdatasync at the end",
                Seconds(t0), ProcessSeconds() - cpu0, static_cast<double>(bytes)};
  std::filesystem::remove(path);
  return f;
}

//! The figure of repeated runs: the median wall and CPU time.
WriteFigure MedianFigure(const std::vector<WriteFigure>& figures) {
  std::vector<double> wall, cpu;
  for (const auto& f : figures) {
    wall.push_back(f.wall);
    cpu.push_back(f.cpu);
  }
  WriteFigure f = figures.front();
  f.wall = Median(wall);
  f.cpu = Median(cpu);
  return f;
}

}  // namespace

RecorderSpeedStudy RunRecorderSpeed(const RecorderSpeedOptions& o) {
  namespace fs = std::filesystem;
  const std::string session = (fs::path(o.folder) / fmt::format("strut-bench-recorder-{}.h5", ::getpid())).string();
  const std::vector<daq::SampleBlock> blocks = Blocks(o);
  const daq::ExperimentDescriptor descriptor = Descriptor(o);
  RecorderSpeedStudy study;
  for (const auto& b : blocks) study.samples += b.size();

  daq::RecorderOptions options;
  options.force = true;
  options.queue_full_timeout = std::chrono::milliseconds(60000);  // a throughput run: the producer may wait
  std::vector<double> stream_wall, stream_cpu, close_wall, close_cpu;
  for (int r = 0; r < o.repeats; ++r) {
    const double cpu0 = ProcessSeconds();
    const auto t0 = Clock::now();
    daq::Recorder recorder = daq::Recorder::Open(session, {"BENCH-1", "bench", "", "", "", {}, "damper", {}}, options);
    recorder.BeginExperiment(descriptor);
    for (const auto& b : blocks) recorder.Append(b);
    recorder.EndExperiment(daq::EndStatus::kComplete);
    // Streaming ends when the last block is durable: Close drains and syncs before converting,
    // so the two phases are timed through the journal's size on disk.
    while (recorder.stats().bytes_written < recorder.stats().bytes_handed)
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    const double cpu1 = ProcessSeconds();
    const auto t1 = Clock::now();
    study.last = recorder.stats();
    study.journal_bytes = fs::file_size(recorder.journal_path());
    recorder.Close();
    stream_wall.push_back(std::chrono::duration<double>(t1 - t0).count());
    stream_cpu.push_back(cpu1 - cpu0);
    close_wall.push_back(Seconds(t1));
    close_cpu.push_back(ProcessSeconds() - cpu1);
    study.session_bytes = static_cast<double>(fs::file_size(session));
    fs::remove(session);
  }
  std::vector<WriteFigure> raw_synced, raw_once;
  for (int r = 0; r < o.repeats; ++r) {
    raw_synced.push_back(RawWrite(session + ".raw", study.journal_bytes, options.sync_interval));
    raw_once.push_back(RawWrite(session + ".raw", study.journal_bytes, std::chrono::milliseconds(0)));
  }
  const double jb = static_cast<double>(study.journal_bytes);
  const WriteFigure stream{"recorder: Append .. journal written", Median(stream_wall), Median(stream_cpu), jb};
  const WriteFigure close{"recorder: Close (journal -> HDF5 session)", Median(close_wall), Median(close_cpu), jb};
  study.figures = {MedianFigure(raw_synced), MedianFigure(raw_once), stream, close,
                   {"recorder: total", stream.wall + close.wall, stream.cpu + close.cpu, jb}};
  study.core_share = stream.cpu / study.samples * o.rate;
  return study;
}

}  // namespace strut::study
