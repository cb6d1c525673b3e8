// Sessions and checks shared by the replay tests and `strut replay`'s (on strut_daq): bit-for-bit
// comparison of two sessions (here and in h5py), a session as the recorder stores a CAN stream, and
// a CAN-over-UDP receiver of what a replay sends.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "python_peer.h"
#include "recorder_fixtures.h"
#include "strut/daq/can_acquisition.h"
#include "strut/daq/recorder.h"
#include "strut/daq/session.h"
#include "test_support.h"

namespace strut::test {

//! Equal to the last bit (tells -0.0 from 0.0, NaN payloads apart).
inline bool SameBits(double a, double b) { return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b); }

// Every sample of every channel and of the time axis, bit for bit, and what the experiments are.
inline void ExpectSameSamples(const daq::Session& original, const daq::Session& again, bool exact_time = true) {
  ASSERT_EQ(original.experiments.size(), again.experiments.size());
  EXPECT_EQ(original.damper_serial, again.damper_serial);
  EXPECT_EQ(original.rig, again.rig);
  EXPECT_EQ(original.profile, again.profile);
  for (std::size_t k = 0; k < original.experiments.size(); ++k) {
    const daq::Experiment& a = original.experiments[k];
    const daq::Experiment& b = again.experiments[k];
    SCOPED_TRACE("experiment " + a.label);
    EXPECT_EQ(a.label, b.label);
    EXPECT_EQ(a.kind, b.kind);
    EXPECT_EQ(a.status, b.status);
    EXPECT_EQ(a.periods, b.periods);
    EXPECT_TRUE(SameBits(a.sample_rate, b.sample_rate));
    EXPECT_TRUE(SameBits(a.frequency, b.frequency));
    EXPECT_TRUE(SameBits(a.amplitude, b.amplitude));
    EXPECT_TRUE(SameBits(a.static_position, b.static_position));
    EXPECT_EQ(a.group, b.group);
    ASSERT_EQ(a.time.size(), b.time.size());
    for (std::size_t i = 0; i < a.time.size(); ++i) {
      if (exact_time) {
        ASSERT_TRUE(SameBits(a.time[i], b.time[i])) << "time[" << i << "] " << a.time[i] << " " << b.time[i];
      } else {
        ASSERT_NEAR(a.time[i], b.time[i], 0.5e-9 * (1 + 1e-6)) << i;  // rounded to whole ns
      }
    }
    ASSERT_EQ(a.channels.size(), b.channels.size());
    for (const daq::Channel& c : a.channels) {
      const daq::Channel* d = b.find_channel(c.name);
      ASSERT_NE(d, nullptr) << c.name;
      EXPECT_EQ(c.units, d->units) << c.name;
      EXPECT_EQ(c.reference, d->reference) << c.name;
      ASSERT_EQ(c.samples.size(), d->samples.size()) << c.name;
      for (std::size_t i = 0; i < c.samples.size(); ++i)
        ASSERT_TRUE(SameBits(c.samples[i], d->samples[i])) << c.name << "[" << i << "] " << c.samples[i] << " "
                                                           << d->samples[i];
    }
    // How the recording ended it; a session of another tool has no recording_end, a recording of
    // its replay says "complete" (the recorder's own attribute).
    for (const char* name : {"recording_end", "requested_periods"}) {
      if (a.extra_attributes.count(name) != 0) {
        ASSERT_EQ(b.extra_attributes.count(name), 1u) << name;
        EXPECT_EQ(a.extra_attributes.at(name), b.extra_attributes.at(name)) << name;
      }
    }
    EXPECT_EQ(a.extra_attributes.count("requested_periods"), b.extra_attributes.count("requested_periods"));
  }
}

// An independent check with h5py: every dataset under /experiments, bit for bit.
inline void ExpectSameDatasetsInH5py(const TempDir& dir, const std::string& a, const std::string& b) {
  const std::string python = test::PythonWithH5py();
  if (python.empty()) {
    std::cerr << "python3 with h5py not found: the h5py comparison is skipped\n";
    return;
  }
  const char* script = R"(
import sys, h5py, numpy as np
with h5py.File(sys.argv[1], "r") as a, h5py.File(sys.argv[2], "r") as b:
    ea, eb = a["experiments"], b["experiments"]
    assert sorted(ea.keys()) == sorted(eb.keys()), (list(ea.keys()), list(eb.keys()))
    n = 0
    for label in ea:
        assert sorted(ea[label].keys()) == sorted(eb[label].keys()), label
        for name in ea[label]:
            x, y = ea[label][name][()], eb[label][name][()]
            assert x.dtype == np.float64 and y.dtype == np.float64, (label, name)
            assert np.array_equal(x.view(np.uint64), y.view(np.uint64)), (label, name)
            n += x.size
print(n, "values identical")
)";
  EXPECT_EQ(test::RunPython(python, dir, script, a + " " + b), 0);
}

// A session as strut's recorder stores a CAN stream: counts of stroke and force (not pressure),
// sequence numbers that jump between experiments, a status that changes mid-experiment, 1 µs of
// timestamp jitter, an aborted and a not-steady experiment, limits and a truth group.
inline std::string RecordedSession(const TempDir& dir) {
  const std::string path = dir.file("recorded.h5");
  daq::Recorder r = daq::Recorder::Open(path, Metadata());
  const daq::Calibration stroke_cal{1e-6, 0.0, 0.0, 0.03};
  const daq::Calibration force_cal = daq::Calibration::FromRange16(-6e4, 6e4);
  std::int64_t t = 7'000'000'000;
  std::uint64_t sequence = 500;
  const auto run = [&](const std::string& label, long periods, long samples, daq::EndStatus end, double rate) {
    daq::ExperimentDescriptor d;
    daq::Experiment& h = d.header;
    h.label = label;
    h.sample_rate = rate;
    h.frequency = rate / 100.0;
    h.amplitude = 0.01;
    h.static_position = 0.015;
    h.periods = periods;
    h.group = "high";
    h.extra_attributes = {{"note", "run " + label}};
    h.channels = {{"stroke", "m", "", {}}, {"force", "N", "", {}}, {"pressure", "Pa", "gauge", {}}};
    d.raw = {{"stroke", stroke_cal}, {"force", force_cal}};
    d.sequence = d.status = true;
    r.BeginExperiment(d);
    const auto period = static_cast<std::int64_t>(std::llround(1e9 / rate));
    for (long first = 0; first < samples; first += 37) {
      daq::SampleBlock b;
      b.values.assign(3, {});
      b.counts.assign(2, {});
      for (long i = first; i < std::min(samples, first + 37); ++i) {
        const auto s = static_cast<std::int32_t>(15000 + std::lround(10000 * std::sin(0.063 * i)));
        const auto f = static_cast<std::int32_t>(std::lround(30000 * std::cos(0.063 * i)));
        b.monotonic_ns.push_back(t + i * period + (i % 3) * 1000);
        b.values[0].push_back(stroke_cal.ToSi(s));
        b.values[1].push_back(force_cal.ToSi(f));
        b.values[2].push_back(1.7e6 + 1e5 * std::sin(0.063 * i + 0.3));  // no counts: arbitrary doubles
        b.counts[0].push_back(s);
        b.counts[1].push_back(f);
        b.sequence.push_back(sequence + i);
        b.status.push_back(i >= 40 && i < 45 ? daq::Quality::kOverRange : 0u);
      }
      r.Append(b);
    }
    r.EndExperiment(end, end == daq::EndStatus::kAborted ? std::nullopt : std::optional<long>(periods));
    t += samples * period + 3'000'000'000;
    sequence += samples + 12345;  // the ramps the rig did not record
  };
  run("a", 3, 300, daq::EndStatus::kComplete, 200.0);
  run("b", 4, 150, daq::EndStatus::kAborted, 200.0);
  run("c", 2, 200, daq::EndStatus::kNotSteady, 200.0);
  r.Close();
  return path;
}

// Receives on `port` in a thread what a replay sends, until the stream has been quiet for a while.
struct Receiver {
  std::unique_ptr<daq::CanAcquisition> acquisition;
  std::vector<std::vector<std::int32_t>> counts;
  std::vector<std::vector<double>> values;
  std::thread thread;
  std::uint16_t port = 0;

  explicit Receiver(const daq::CanAcquisitionOptions& options) : counts(options.channels.size()), values(options.channels.size()) {
    auto transport = daq::UdpCanTransport::Listen("127.0.0.1", 0);
    port = transport->local_port();
    acquisition = std::make_unique<daq::CanAcquisition>(std::move(transport), options);
    acquisition->Start();
    thread = std::thread([this] {
      for (int quiet = 0; quiet < 6;) {  // 0.6 s without samples: the replay is over
        const daq::AcquiredBlock b = acquisition->Read(std::chrono::milliseconds(100));
        quiet = b.empty() ? quiet + 1 : 0;
        for (std::size_t c = 0; c < b.counts.size(); ++c) {
          counts[c].insert(counts[c].end(), b.counts[c].begin(), b.counts[c].end());
          values[c].insert(values[c].end(), b.values[c].begin(), b.values[c].end());
        }
      }
    });
  }
  void Join() { thread.join(); }
};

}  // namespace strut::test
