// A recording process for the kill -9 test (tests/test_recorder.cpp): records periodic experiments
// from a fast synthetic source through daq::Recorder and, after every Append that returned, appends
// "<samples handed over so far> <CLOCK_MONOTONIC ns>" to a report file with write(2), so the line
// survives a SIGKILL; a first line "0 <ns>" says the recorder is open. force = the global sample index, so the test can tell exactly which samples a
// file holds.
//
// recorder_child SESSION REPORT RATE_HZ SPEED BLOCK EXPERIMENTS PERIODS FREQUENCY_HZ SYNC_MS
#include <fcntl.h>
#include <time.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>

#include "strut/daq/recorder.h"

namespace {

std::int64_t NowNs() {
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);
  return std::int64_t{t.tv_sec} * 1'000'000'000 + t.tv_nsec;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 10) {
    std::fprintf(stderr, "usage: recorder_child SESSION REPORT RATE SPEED BLOCK EXPERIMENTS PERIODS FREQUENCY SYNC_MS\n");
    return 2;
  }
  const std::string session = argv[1];
  const int report = ::open(argv[2], O_WRONLY | O_CREAT | O_TRUNC | O_APPEND | O_CLOEXEC, 0644);
  const double rate = std::atof(argv[3]);
  const double speed = std::atof(argv[4]);
  const long block = std::atol(argv[5]);
  const int experiments = std::atoi(argv[6]);
  const long periods = std::atol(argv[7]);
  const double frequency = std::atof(argv[8]);
  if (report < 0) {
    std::perror(argv[2]);
    return 2;
  }
  try {
    strut::daq::RecorderOptions options;
    options.sync_interval = std::chrono::milliseconds(std::atol(argv[9]));
    strut::daq::Recorder recorder = strut::daq::Recorder::Open(
        session, {"KILL-9", "recorder_child", "tester", "", "synthetic", {{"stroke_max", 0.25}}, "damper", {}},
        options);
    const std::string opened = "0 " + std::to_string(NowNs()) + "\n";  // the test's start signal
    if (::write(report, opened.data(), opened.size()) < 0) return 3;
    const long per_experiment = std::lround(periods * rate / frequency);
    const std::int64_t wall_start = NowNs();
    long handed = 0;
    for (int k = 0; k < experiments; ++k) {
      strut::daq::ExperimentDescriptor d;
      strut::daq::Experiment& h = d.header;
      h.label = "e" + std::to_string(k);
      h.sample_rate = rate;
      h.frequency = frequency;
      h.amplitude = 0.01;
      h.static_position = 0.1;
      h.periods = periods;
      h.channels = {{"stroke", "m", "", {}}, {"force", "N", "", {}}, {"pressure", "Pa", "gauge", {}}};
      d.raw = {{"stroke", {1e-6, 0.0, 0.0, 0.25}}};
      d.sequence = d.status = true;
      recorder.BeginExperiment(d);
      // The sample clock of this experiment starts 1 s after the previous one's.
      const std::int64_t t0 = 1'000'000'000LL * (1 + k * 1000);
      for (long i = 0; i < per_experiment; i += block) {
        const long n = std::min(block, per_experiment - i);
        strut::daq::SampleBlock b;
        b.values.assign(3, {});
        b.counts.assign(1, {});
        for (long j = i; j < i + n; ++j) {
          const double stroke = 0.1 + 0.01 * std::sin(2 * M_PI * frequency * j / rate);
          b.monotonic_ns.push_back(t0 + std::llround(j * 1e9 / rate));
          b.values[0].push_back(stroke);
          b.values[1].push_back(static_cast<double>(handed + (j - i)));
          b.values[2].push_back(1e5 + j);
          b.counts[0].push_back(static_cast<std::int32_t>(std::lround(stroke / 1e-6)));
          b.sequence.push_back(static_cast<std::uint64_t>(handed + (j - i)));
          b.status.push_back(0);
        }
        // Paced: sample `handed` is due at handed / rate / speed seconds of wall time.
        const auto due = wall_start + static_cast<std::int64_t>(handed / rate / speed * 1e9);
        const std::int64_t wait = due - NowNs();
        if (wait > 0) std::this_thread::sleep_for(std::chrono::nanoseconds(wait));
        recorder.Append(b);
        handed += n;
        const std::string line = std::to_string(handed) + " " + std::to_string(NowNs()) + "\n";
        if (::write(report, line.data(), line.size()) < 0) return 3;
        if ((i / block) % 50 == 0) recorder.Event(b.monotonic_ns.front(), "note", "block " + std::to_string(i / block));
      }
      recorder.EndExperiment(strut::daq::EndStatus::kComplete);
    }
    recorder.Close();
    const std::string done = "closed\n";
    if (::write(report, done.data(), done.size()) < 0) return 3;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "recorder_child: %s\n", e.what());
    return 1;
  }
  return 0;
}
