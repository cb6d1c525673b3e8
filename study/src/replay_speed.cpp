#include "strut/study/replay_speed.h"

#include <fmt/format.h>

#include <cmath>
#include <filesystem>

#include "strut/daq/replay.h"
#include "strut/study/cpu_time.h"

namespace strut::study {
namespace {

double MonotonicSeconds() { return static_cast<double>(daq::MonotonicNs()) / 1e9; }

}  // namespace

daq::Session ReplayBenchSession(double seconds, double rate) {
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

std::vector<ReplayFigure> MeasureReplay(const daq::Session& session, const std::string& recording_path) {
  std::vector<ReplayFigure> figures;
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
    daq::Recorder recorder = daq::Recorder::Open(recording_path, daq::ReplayMetadata(session), options);
    daq::PlayReplay(replay, &recorder);
    recorder.Close();
    figures.push_back({"replay into the recorder, session written", MonotonicSeconds() - t0, ProcessSeconds() - cpu0});
    std::filesystem::remove(recording_path);
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
  return figures;
}

}  // namespace strut::study
