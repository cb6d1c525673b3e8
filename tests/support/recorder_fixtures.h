// Recordings made by strut's recorder for the recorder and replay tests (on strut_daq): the
// metadata, experiments and sample blocks they record, and a journal cut off mid-experiment.
#pragma once

#include <time.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <string>
#include <thread>

#include "strut/daq/recorder.h"
#include "strut/daq/session.h"

namespace strut::test {

//! CLOCK_MONOTONIC in ns, the clock the recorder stamps its blocks with.
inline std::int64_t NowNs() {
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);
  return std::int64_t{t.tv_sec} * 1'000'000'000 + t.tv_nsec;
}

//! The recording metadata of a damper on shaker-2: serial, operator, limits and a truth group.
inline daq::RecordingMetadata Metadata() {
  daq::RecordingMetadata m;
  m.damper_serial = "MLG-0042";
  m.rig = "shaker-2";
  m.operator_name = "J. Doe";
  m.matrix = "standard";
  m.limits = {{"stroke_max", 0.25}, {"force_max", 20000.0}};
  m.groups = {{"truth", {{"model", std::string("2dof")}, {"theta1", 1.5}}, {}}};
  return m;
}

// A periodic experiment at 200 Hz, 2 Hz: 100 samples a period; stroke with raw counts.
inline daq::ExperimentDescriptor Periodic(const std::string& label, long periods = 3) {
  daq::ExperimentDescriptor d;
  daq::Experiment& h = d.header;
  h.label = label;
  h.sample_rate = 200.0;
  h.frequency = 2.0;
  h.amplitude = 0.01;
  h.static_position = 0.1;
  h.periods = periods;
  h.group = "high";
  h.extra_attributes = {{"note", "first try"}};
  h.channels = {{"stroke", "m", "", {}}, {"force", "N", "", {}}, {"pressure", "Pa", "gauge", {}}};
  d.raw = {{"stroke", {1e-6, 0.0, 0.0, 0.25}}};
  d.sequence = d.status = true;
  return d;
}

// Samples first..first+n of an experiment at 200 Hz starting at t0_ns; force = global index g0 + i.
inline daq::SampleBlock Block(std::int64_t t0_ns, long first, long n, long g0 = 0) {
  daq::SampleBlock b;
  b.values.assign(3, {});
  b.counts.assign(1, {});
  for (long i = first; i < first + n; ++i) {
    const double stroke = 0.1 + 0.01 * std::sin(2 * M_PI * 2.0 * i / 200.0);
    b.monotonic_ns.push_back(t0_ns + i * 5'000'000 + (i % 3) * 1000);  // 1 us of jitter
    b.values[0].push_back(stroke);
    b.values[1].push_back(static_cast<double>(g0 + i));
    b.values[2].push_back(2e5 + i);
    b.counts[0].push_back(static_cast<std::int32_t>(std::lround(stroke / 1e-6)));
    b.sequence.push_back(static_cast<std::uint64_t>(g0 + i));
    b.status.push_back(i == 7 ? 4u : 0u);
  }
  return b;
}

// Records experiment a (100 samples, complete) and `b_samples` of b in blocks of `block`, with a
// trip event, and copies the journal to `copy` as a crash at that moment would have left it.
inline void RecordCutOff(const std::string& path, const std::string& copy, long b_samples, long block) {
  daq::Recorder r = daq::Recorder::Open(path, Metadata());
  r.BeginExperiment(Periodic("a", 1));
  r.Append(Block(0, 0, 100));
  r.EndExperiment(daq::EndStatus::kComplete);
  r.BeginExperiment(Periodic("b", 2));
  for (long i = 0; i < b_samples; i += block) r.Append(Block(1'000'000'000, i, block, 100));
  r.Event(1'000'000'000, "trip", "stroke limit");
  while (r.stats().bytes_written < r.stats().bytes_handed) std::this_thread::sleep_for(std::chrono::milliseconds(2));
  std::filesystem::copy_file(r.journal_path(), copy);
}

// A run as the matrix runner records one, with the limits it records (rig::RunMetadata) and
// events before, during and after its experiments: a note before a; a mark in a at 0.3 s; a
// force-limit trip in b at `trip_s`; a pause after b. Experiments a and b of `periods` periods
// (Periodic, Block: 200 Hz, force = sample index + 100 in b); b starts 1 s after a ends.
inline void RecordRunWithEvents(const std::string& path, long periods, double trip_s) {
  daq::RecordingMetadata m = Metadata();
  m.limits = {{"stroke_min", -0.008}, {"stroke_max", 0.27},     {"force_min", -1000.0}, {"force_max", 1000.0},
              {"pressure_min", -1e5}, {"pressure_max", 18e6},   {"following_error", 0.01}};
  daq::Recorder r = daq::Recorder::Open(path, m);
  const long n = periods * 100;
  const std::int64_t a0 = 1'000'000'000, b0 = a0 + (n + 200) * 5'000'000LL;
  r.Event(a0 - 200'000'000, "note", "top-out reference skipped");
  r.BeginExperiment(Periodic("a", periods));
  for (long i = 0; i < n; i += 50) r.Append(Block(a0, i, 50));
  r.Event(a0 + 300'000'000, "mark", "operator's mark in a");
  r.EndExperiment(daq::EndStatus::kComplete);
  r.BeginExperiment(Periodic("b", periods));
  for (long i = 0; i < n; i += 50) r.Append(Block(b0, i, 50, 100));
  r.Event(b0 + static_cast<std::int64_t>(trip_s * 1e9), "trip", "force-limit: force above 1000 N for 3 samples (action indicate)");
  r.EndExperiment(daq::EndStatus::kComplete);
  r.Event(b0 + n * 5'000'000LL + 100'000'000, "paused", "paused after experiment b");
  r.Close();
}

}  // namespace strut::test
