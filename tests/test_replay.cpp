// Replay of recorded sessions (daq/replay.h, docs/replay.md): record, replay, re-record gives the
// same samples bit for bit (SI values, counts, sequence, status, time axis) for sessions of
// `strut sim matrix`, of strut's recorder and of another tool (h5py); identification of the
// original and of the re-recording agree exactly; over UDP a CanAcquisition receives the counts;
// experiment boundaries, pacing and bad input.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <bit>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <thread>

#include "python_peer.h"
#include "strut/daq/can_acquisition.h"
#include "strut/daq/replay.h"
#include "strut/rig/steady_state.h"
#include "test_support.h"

namespace strut::daq {
namespace {

using namespace std::chrono_literals;
using test::RunStrut;
using test::TempDir;
namespace fs = std::filesystem;

bool SameBits(double a, double b) { return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b); }

// Every sample of every channel and of the time axis, bit for bit, and what the experiments are.
void ExpectSameSamples(const Session& original, const Session& again, bool exact_time = true) {
  ASSERT_EQ(original.experiments.size(), again.experiments.size());
  EXPECT_EQ(original.damper_serial, again.damper_serial);
  EXPECT_EQ(original.rig, again.rig);
  EXPECT_EQ(original.profile, again.profile);
  for (std::size_t k = 0; k < original.experiments.size(); ++k) {
    const Experiment& a = original.experiments[k];
    const Experiment& b = again.experiments[k];
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
    for (const Channel& c : a.channels) {
      const Channel* d = b.find_channel(c.name);
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
void ExpectSameDatasetsInH5py(const TempDir& dir, const std::string& a, const std::string& b) {
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

// The parameters `strut identify` estimates from `session` (JSON array).
nlohmann::json IdentifiedParameters(const TempDir& dir, const std::string& session, const std::string& stem) {
  const std::string json = dir.file(stem + ".json");
  const test::CommandResult r = RunStrut("identify --no-progress " + session + " --json " + json);
  EXPECT_TRUE(r.exit_code == 0 || r.exit_code == 3) << r.output;
  std::ifstream in(json);
  nlohmann::json j;
  in >> j;
  return j.at("parameters");
}

TEST(Replay, SimMatrixSessionReRecordsBitForBitAndIdentifiesExactlyTheSame) {
  TempDir dir;
  const std::string original = dir.file("unit7.h5"), again = dir.file("replayed.h5");
  ASSERT_EQ(RunStrut("sim matrix --draw 7 -o " + original).exit_code, 0);
  const test::CommandResult r = RunStrut("replay " + original + " -o " + again);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("14 experiments"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("derived"), std::string::npos) << r.output;  // a simulated session has no counts
  const Session a = ReadSession(original), b = ReadSession(again);
  ExpectSameSamples(a, b);
  ASSERT_NE(b.find_metadata("truth"), nullptr);  // the drawn unit's truth goes along
  // The runner's steady-state detector on the replayed stream says what it says on the file.
  for (const Experiment& e : a.experiments) {
    const rig::SteadyStateVerdict v = rig::DetectSteadyState(rig::SummariseExperiment(e), {});
    const std::string row = fmt::format("{} ({} cycles)", v.steady ? "yes" : "no", v.cycles);
    const std::size_t line = r.output.find("\n" + e.label + " ");
    ASSERT_NE(line, std::string::npos) << e.label << "\n" << r.output;
    EXPECT_EQ(r.output.substr(line, r.output.find('\n', line + 1) - line).find(row) != std::string::npos, true)
        << e.label << ": expected " << row << "\n" << r.output;
  }
  ExpectSameDatasetsInH5py(dir, original, again);

  const nlohmann::json p = IdentifiedParameters(dir, original, "original");
  const nlohmann::json q = IdentifiedParameters(dir, again, "replayed");
  ASSERT_EQ(p.size(), q.size());
  ASSERT_GT(p.size(), 5u);
  for (std::size_t k = 0; k < p.size(); ++k) {
    EXPECT_EQ(p[k].at("index"), q[k].at("index"));
    EXPECT_TRUE(SameBits(p[k].at("value").get<double>(), q[k].at("value").get<double>()))
        << p[k].at("index") << " " << p[k].at("value") << " " << q[k].at("value");
  }
}

// A session as strut's recorder stores a CAN stream: counts of stroke and force (not pressure),
// sequence numbers that jump between experiments, a status that changes mid-experiment, 1 µs of
// timestamp jitter, an aborted and a not-steady experiment, limits and a truth group.
std::string RecordedSession(const TempDir& dir) {
  const std::string path = dir.file("recorded.h5");
  RecordingMetadata m;
  m.damper_serial = "MLG-0042";
  m.rig = "shaker-2";
  m.operator_name = "J. Doe";
  m.matrix = "standard";
  m.limits = {{"stroke_max", 0.25}, {"force_max", 20000.0}};
  m.groups = {{"truth", {{"model", std::string("2dof")}, {"theta1", 1.5}}, {}}};
  Recorder r = Recorder::Open(path, m);
  const Calibration stroke_cal{1e-6, 0.0, 0.0, 0.03};
  const Calibration force_cal = Calibration::FromRange16(-6e4, 6e4);
  std::int64_t t = 7'000'000'000;
  std::uint64_t sequence = 500;
  const auto run = [&](const std::string& label, long periods, long samples, EndStatus end, double rate) {
    ExperimentDescriptor d;
    Experiment& h = d.header;
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
      SampleBlock b;
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
        b.status.push_back(i >= 40 && i < 45 ? Quality::kOverRange : 0u);
      }
      r.Append(b);
    }
    r.EndExperiment(end, end == EndStatus::kAborted ? std::nullopt : std::optional<long>(periods));
    t += samples * period + 3'000'000'000;
    sequence += samples + 12345;  // the ramps the rig did not record
  };
  run("a", 3, 300, EndStatus::kComplete, 200.0);
  run("b", 4, 150, EndStatus::kAborted, 200.0);
  run("c", 2, 200, EndStatus::kNotSteady, 200.0);
  r.Close();
  return path;
}

// Watches the stream as a steady-state detector would.
struct Watcher : ReplayObserver {
  std::vector<std::string> log;
  std::vector<std::size_t> sets;
  std::vector<std::uint64_t> indices;
  std::vector<std::uint32_t> flags;
  void BeginExperiment(const ReplayedExperiment& x) override {
    log.push_back("begin " + x.header.label);
    sets.push_back(0);
  }
  void Block(const ReplayedExperiment&, const AcquiredBlock& b) override {
    sets.back() += b.size();
    for (std::size_t i = 0; i < b.size(); ++i) {
      indices.push_back(b.first_index + i);
      flags.push_back(b.quality.flags);
    }
  }
  void EndExperiment(const ReplayedExperiment& x) override { log.push_back("end " + x.header.label); }
};

TEST(Replay, RecorderSessionReRecordsCountsSequenceStatusAndCalibrationBitForBit) {
  TempDir dir;
  const std::string original = RecordedSession(dir), again = dir.file("again.h5");
  auto replay = ReplayAcquisition::Open(original);
  ASSERT_EQ(replay->experiments().size(), 3u);
  const ReplayedExperiment& a = replay->experiments()[0];
  EXPECT_EQ(a.recorded_counts, (std::vector<bool>{true, true, false}));
  EXPECT_TRUE(a.recorded_sequence);
  EXPECT_TRUE(a.recorded_status);
  EXPECT_TRUE(a.exact_time);
  EXPECT_EQ(replay->experiments()[1].end, EndStatus::kAborted);
  EXPECT_EQ(replay->experiments()[1].header.periods, 4);  // as requested
  EXPECT_EQ(replay->experiments()[2].end, EndStatus::kNotSteady);
  Watcher watcher;
  {
    Recorder r = Recorder::Open(again, ReplayMetadata(replay->session()));
    const ReplayFigures f = PlayReplay(*replay, &r, &watcher);
    r.Close();
    EXPECT_EQ(f.sample_sets, 650u);
    EXPECT_EQ(f.experiments, 3u);
  }
  EXPECT_EQ(watcher.log, (std::vector<std::string>{"begin a", "end a", "begin b", "end b", "begin c", "end c"}));
  EXPECT_EQ(watcher.sets, (std::vector<std::size_t>{300, 150, 200}));
  const Session s = ReadSession(original), t = ReadSession(again);
  ExpectSameSamples(s, t);
  ExpectSameDatasetsInH5py(dir, original, again);
  // What the stream carried is what the session holds: indices are its sequence, qualities its status.
  std::size_t n = 0;
  for (const Experiment& e : s.experiments)
    for (std::size_t i = 0; i < e.sample_count(); ++i, ++n) {
      ASSERT_EQ(static_cast<double>(watcher.indices[n]), e.channel("sequence").samples[i]) << e.label << i;
      ASSERT_EQ(static_cast<double>(watcher.flags[n]), e.channel("status").samples[i]) << e.label << i;
    }
  // Calibration, limits, operator, matrix and the truth group go along.
  const MetadataGroup* cal = t.find_metadata("recording")->find_group("calibration");
  ASSERT_NE(cal, nullptr);
  for (const char* label : {"a", "b", "c"})
    for (const char* channel : {"stroke", "force"}) {
      const MetadataGroup* x = s.find_metadata("recording")->find_group("calibration")->find_group(label)->find_group(channel);
      const MetadataGroup* y = cal->find_group(label)->find_group(channel);
      ASSERT_NE(y, nullptr) << label << channel;
      for (const char* attribute : {"gain", "offset", "range_min", "range_max"})
        EXPECT_TRUE(SameBits(*x->number(attribute), *y->number(attribute))) << label << channel << attribute;
    }
  EXPECT_EQ(*t.find_metadata("recording")->find_group("limits")->number("force_max"), 20000.0);
  EXPECT_EQ(*t.find_metadata("recording")->text("operator"), "J. Doe");
  EXPECT_EQ(*t.find_metadata("truth")->number("theta1"), 1.5);
  EXPECT_EQ(t.experiment("a").extra_attributes.at("note"), "run a");
  std::string events;
  for (const auto& [kind, text] : test::SessionEvents(t)) events += kind + ": " + text + "\n";
  EXPECT_NE(events.find("replay: replay of " + original + " as fast as possible"), std::string::npos) << events;
}

TEST(Replay, SessionOfAnotherToolWithArbitraryDoublesReRecordsBitForBit) {
  const std::string python = test::PythonWithH5py();
  if (python.empty()) GTEST_SKIP() << "python3 with h5py and numpy not found";
  TempDir dir;
  const std::string original = dir.file("other.h5"), again = dir.file("again.h5");
  // Values of every magnitude and sign (-0.0, subnormals, 1e300), time = i / rate as numpy writes
  // it; experiment "y" at 2048 Hz, whose steps are no whole number of nanoseconds.
  const char* script = R"(
import sys, h5py, numpy as np
rng = np.random.default_rng(11)
with h5py.File(sys.argv[1], "w") as h:
    h.attrs["format"] = "damper-session"; h.attrs["format_version"] = 1
    h.attrs["created_utc"] = "2026-01-02T03:04:05Z"; h.attrs["damper_serial"] = "OTHER-9"; h.attrs["rig"] = "their rig"
    for label, rate, f, periods in (("x", 1000.0, 2.0, 4), ("y", 2048.0, 2.0, 3)):
        g = h.create_group("experiments/" + label)
        n = int(round(periods * rate / f))
        g.attrs.update(kind="periodic", status="complete", sample_rate=rate, frequency=f, amplitude=0.02,
                       static_position=0.1, waveform="sine", periods=periods)
        g["time"] = np.arange(n) / rate
        stroke = 0.1 + 0.02 * np.sin(2 * np.pi * f * np.arange(n) / rate) + rng.standard_normal(n) * 1e-7
        force = rng.standard_normal(n) * 10.0 ** rng.integers(-5, 5, n)
        force[:4] = [-0.0, 5e-324, 1e300, -1e300]
        pressure = 2e6 + rng.standard_normal(n) * 1e4
        for name, units, v in (("stroke", "m", stroke), ("force", "N", force), ("pressure", "Pa", pressure)):
            g[name] = v; g[name].attrs["units"] = units
        g["pressure"].attrs["reference"] = "absolute"
)";
  ASSERT_EQ(test::RunPython(python, dir, script, original), 0);
  const test::CommandResult r = RunStrut("replay " + original + " -o " + again);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("experiment 'y': its time axis is not on whole nanoseconds"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("experiment 'x': its time axis"), std::string::npos) << r.output;
  const Session a = ReadSession(original), b = ReadSession(again);
  Session ax = a, bx = b, ay = a, by = b;  // x: bit for bit in full; y: samples bit for bit, time to 0.5 ns
  ax.experiments = {a.experiment("x")};
  bx.experiments = {b.experiment("x")};
  ay.experiments = {a.experiment("y")};
  by.experiments = {b.experiment("y")};
  ExpectSameSamples(ax, bx);
  ExpectSameSamples(ay, by, false);
  EXPECT_FALSE(SameBits(-0.0, 0.0));  // the comparison does tell -0.0 from 0.0
  EXPECT_TRUE(SameBits(b.experiment("x").channel("force").samples[0], -0.0));
}

// An in-memory session of another tool: experiments at 200 Hz and 500 Hz, no counts.
Session TwoRateSession() {
  Session s;
  s.source_path = "two-rate.h5";
  s.created_utc = "2026-01-01T00:00:00Z";
  s.damper_serial = "X";
  s.rig = "Y";
  for (const auto& [label, rate, n] : {std::tuple{"p", 200.0, 400}, std::tuple{"q", 500.0, 250}}) {
    Experiment e;
    e.label = label;
    e.sample_rate = rate;
    e.frequency = rate / 50;
    e.amplitude = 0.01;
    e.periods = n / 50;
    Channel stroke{"stroke", "m", "", {}}, force{"force", "N", "", {}}, pressure{"pressure", "Pa", "gauge", {}};
    for (int i = 0; i < n; ++i) {
      e.time.push_back(i / rate);
      stroke.samples.push_back(0.1 + 0.01 * std::sin(0.1 * i));
      force.samples.push_back(1000.0 * std::cos(0.1 * i) + (label[0] == 'q' ? 5000.0 : 0.0));
      pressure.samples.push_back(1e6);
    }
    e.channels = {stroke, force, pressure};
    s.experiments.push_back(std::move(e));
  }
  return s;
}

TEST(ReplayAcquisition, BlocksNeverSpanExperimentsAndCarryTheRecordedTimeAxisAndDerivedCounts) {
  const Session s = TwoRateSession();
  ReplayOptions o;
  o.block_sets = 64;
  ReplayAcquisition replay(s, o);
  replay.Start();
  EXPECT_EQ(replay.next_experiment(), 0u);
  EXPECT_EQ(replay.description().sample_rate, 200.0);
  std::vector<std::vector<AcquiredBlock>> blocks(2);
  while (!replay.finished()) {
    const std::size_t k = replay.next_experiment();
    AcquiredBlock b = replay.Read(100ms);
    ASSERT_FALSE(b.empty());
    ASSERT_LE(b.size(), 64u);
    blocks[k].push_back(std::move(b));
    if (k == 0 && !replay.finished() && replay.next_experiment() == 1) {
      EXPECT_EQ(blocks[0].back().time_ns.size() + (blocks[0].size() - 1) * 64, 400u);  // the last block of p
      EXPECT_EQ(replay.description().sample_rate, 500.0);
    }
  }
  EXPECT_TRUE(replay.Read(1s).empty());  // at the end: at once
  ASSERT_EQ(blocks[0].size(), 7u);       // 6 x 64 + 16: the boundary cuts a block short
  ASSERT_EQ(blocks[1].size(), 4u);
  const std::int64_t start = blocks[0][0].time_ns[0];
  std::uint64_t index = 0;
  for (std::size_t k = 0; k < 2; ++k) {
    const Experiment& e = s.experiments[k];
    std::size_t i = 0;
    for (const AcquiredBlock& b : blocks[k]) {
      EXPECT_EQ(b.first_index, index);  // consecutive from 0: the session has no sequence
      EXPECT_EQ(b.lost_before, 0u);
      EXPECT_TRUE(b.quality.valid());
      for (std::size_t j = 0; j < b.size(); ++j, ++i, ++index) {
        // p from 0, q one 200 Hz period after p's last sample (2 s).
        const std::int64_t expected = start + (k == 0 ? 0 : 2'000'000'000) + std::llround(e.time[i] * 1e9);
        ASSERT_EQ(b.time_ns[j], expected) << e.label << i;
        for (std::size_t c = 0; c < 3; ++c) {
          ASSERT_TRUE(SameBits(b.values[c][j], e.channels[c].samples[i]));
          // Counts derived from the values: the nearest count of a calibration over the session's range.
          const Calibration& cal = replay.experiments()[k].stream.channels[c].calibration;
          ASSERT_LE(std::abs(cal.ToSi(b.counts[c][j]) - b.values[c][j]), 0.5 * cal.gain * (1 + 1e-6)) << c;
        }
      }
    }
  }
  // One calibration per channel for the session: the CAN receiver's.
  EXPECT_EQ(replay.experiments()[0].stream.channels[1].calibration.gain,
            replay.experiments()[1].stream.channels[1].calibration.gain);
  EXPECT_EQ(replay.stats().sample_sets, 650u);
  EXPECT_NEAR(replay.recorded_seconds(), 2.0 + 0.5, 1e-12);
}

TEST(ReplayAcquisition, PacedReplayKeepsTheRecordedPaceOverTheSpeedAndNeverOverstaysATimeout) {
  ReplayOptions o;
  o.speed = 5.0;        // 2.5 s recorded in 0.5 s
  o.block_sets = 20;    // 100 ms recorded at 200 Hz: 20 ms of wall time
  ReplayAcquisition replay(TwoRateSession(), o);
  replay.Start();
  const std::int64_t started = MonotonicNs();
  std::int64_t longest_read = 0;
  std::size_t sets = 0, cut_short = 0;
  while (!replay.finished()) {
    const std::int64_t before = MonotonicNs();
    const AcquiredBlock b = replay.Read(3ms);
    const std::int64_t after = MonotonicNs();
    longest_read = std::max(longest_read, after - before);
    if (b.empty()) continue;
    sets += b.size();
    if (b.size() < 20 && replay.next_experiment() == 0) ++cut_short;
    // Never before the last sample of the block is due at that pace.
    const double due = static_cast<double>(b.time_ns.back() - started) / o.speed;
    ASSERT_GE(static_cast<double>(after - started), due - 2e6) << "a block came early";
  }
  const double wall = static_cast<double>(MonotonicNs() - started) / 1e9;
  EXPECT_EQ(sets, 650u);
  EXPECT_GT(cut_short, 0u);  // 3 ms timeouts within 20 ms blocks: the sets due by then
  EXPECT_GE(wall, 0.49);
  EXPECT_LT(wall, 5.0);
  EXPECT_LT(longest_read, 200'000'000) << "a Read overstayed its 3 ms timeout by far";

  // Nothing due within the timeout: an empty block after the timeout, not before, not much after.
  o.speed = 1e-3;  // the second sample is due 5 s after the first
  ReplayAcquisition slow(TwoRateSession(), o);
  slow.Start();
  EXPECT_EQ(slow.Read(5ms).size(), 1u);  // the first is due at Start
  const std::int64_t before = MonotonicNs();
  EXPECT_TRUE(slow.Read(5ms).empty());
  const std::int64_t waited = MonotonicNs() - before;
  EXPECT_GE(waited, 5'000'000);
  EXPECT_LT(waited, 200'000'000);
}

TEST(ReplayAcquisition, ReadBeforeStartAndBadOptionsAreErrors) {
  ReplayAcquisition replay(TwoRateSession());
  EXPECT_THROW(replay.Read(1ms), DeviceError);
  replay.Start();
  replay.Stop();
  EXPECT_THROW(replay.Read(1ms), DeviceError);
  for (double speed : {-1.0, std::nan(""), HUGE_VAL}) {
    ReplayOptions o;
    o.speed = speed;
    try {
      ReplayAcquisition bad(TwoRateSession(), o);
      FAIL() << "speed " << speed << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("speed"), std::string::npos) << e.what();
    }
  }
}

TEST(ReplayAcquisition, CountsThatNoRecorderWroteAreRefusedNamingTheExperimentAndChannel) {
  TempDir dir;
  Session s = ReadSession(RecordedSession(dir));
  Channel* counts = nullptr;
  for (Channel& c : s.experiments[1].channels)
    if (c.name == "force_counts") counts = &c;
  ASSERT_NE(counts, nullptr);
  counts->samples[3] = 1.5;
  try {
    ReplayAcquisition replay(s);
    FAIL() << "accepted";
  } catch (const SessionError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("experiment 'b'"), std::string::npos) << what;
    EXPECT_NE(what.find("'force_counts'"), std::string::npos) << what;
    EXPECT_NE(what.find("sample 3"), std::string::npos) << what;
  }
}

// A recorder's counts may be wider than a CAN sample frame's 16 bits: sending refuses them, naming
// the experiment, channel and sample; the counts derived for the other channels always fit.
TEST(ReplayCanOptions, RecordedCountsBeyondSixteenBitsAreRefusedNamingTheExperimentAndChannel) {
  TempDir dir;
  Session s = ReadSession(RecordedSession(dir));
  ReplayOptions o;
  o.speed = 1.0;
  EXPECT_NO_THROW(ReplayCanOptions(ReplayAcquisition(s, o)));  // derived pressure counts included
  for (Channel& c : s.experiments[2].channels)
    if (c.name == "stroke_counts") c.samples[7] = 40000.0;
  try {
    ReplayCanOptions(ReplayAcquisition(s, o));
    FAIL() << "accepted";
  } catch (const SessionError& e) {
    EXPECT_NE(std::string(e.what()).find("experiment 'c': channel 'stroke': count 40000 at sample 7 does not fit the 16 "
                                         "bits"),
              std::string::npos)
        << e.what();
  }
}

// Receives on `port` in a thread what a replay sends, until the stream has been quiet for a while.
struct Receiver {
  std::unique_ptr<CanAcquisition> acquisition;
  std::vector<std::vector<std::int32_t>> counts;
  std::vector<std::vector<double>> values;
  std::thread thread;
  std::uint16_t port = 0;

  explicit Receiver(const CanAcquisitionOptions& options) : counts(options.channels.size()), values(options.channels.size()) {
    auto transport = UdpCanTransport::Listen("127.0.0.1", 0);
    port = transport->local_port();
    acquisition = std::make_unique<CanAcquisition>(std::move(transport), options);
    acquisition->Start();
    thread = std::thread([this] {
      for (int quiet = 0; quiet < 6;) {  // 0.6 s without samples: the replay is over
        const AcquiredBlock b = acquisition->Read(100ms);
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

TEST(Replay, OverUdpTheSamplesArriveWithTheirCounts) {
  TempDir dir;
  ReplayOptions o;
  o.speed = 10.0;  // 650 sets at 200 Hz: 0.33 s
  auto replay = ReplayAcquisition::Open(RecordedSession(dir), o);
  const CanAcquisitionOptions can = ReplayCanOptions(*replay);
  EXPECT_EQ(can.sample_rate, 2000.0);  // the receiver's rate: recorded rate x speed
  EXPECT_FALSE(can.layout.fd);          // 2 kHz fits classic frames
  ASSERT_EQ(can.channels.size(), 3u);
  Receiver receiver(can);
  const ReplayFigures f = SendReplay(*replay, UdpCanTransport::Connect("127.0.0.1", receiver.port), can);
  receiver.Join();
  EXPECT_EQ(f.sample_sets, 650u);
  EXPECT_EQ(receiver.acquisition->stats().lost_sample_sets, 0u);
  EXPECT_EQ(receiver.acquisition->stats().corrupt_frames, 0u);
  const Session& s = replay->session();
  for (std::size_t c = 0; c < 3; ++c) {
    ASSERT_EQ(receiver.counts[c].size(), 650u) << c;
    std::size_t n = 0;
    for (std::size_t k = 0; k < 3; ++k) {
      const std::vector<std::int32_t>& sent = replay->counts(k, c);
      const Channel& si = s.experiments[k].channel(can.channels[c].name);
      for (std::size_t i = 0; i < sent.size(); ++i, ++n) {
        ASSERT_EQ(receiver.counts[c][n], sent[i]) << c << " " << n;  // counts exactly
        if (replay->experiments()[k].recorded_counts[c]) {
          // A CAN recording's SI values are its counts calibrated: they arrive exactly.
          ASSERT_TRUE(SameBits(receiver.values[c][n], si.samples[i])) << c << " " << n;
        } else {
          ASSERT_LE(std::abs(receiver.values[c][n] - si.samples[i]), 0.5 * can.channels[c].calibration.gain * (1 + 1e-6));
        }
      }
    }
  }
}

TEST(Replay, OverUdpFasterThanRealTimeEveryCountArrivesAtTheRateTimesTheSpeed) {
  // 100 s at 200 Hz sent at 1000 times the pace: a 200 kHz stream, CAN FD; a receiver at the
  // recorded rate would take the frames for a restarted module and drop most of them.
  Session s = TwoRateSession();
  s.experiments.pop_back();
  Experiment& e = s.experiments[0];
  const int n = 20000;
  e.time.clear();
  for (auto& c : e.channels) c.samples.clear();
  for (int i = 0; i < n; ++i) {
    e.time.push_back(i / 200.0);
    e.channels[0].samples.push_back(0.1 + 0.01 * std::sin(0.1 * i));
    e.channels[1].samples.push_back(1000.0 * std::cos(0.1 * i));
    e.channels[2].samples.push_back(1e6 + i);
  }
  e.periods = n / 50;
  ReplayOptions o;
  o.speed = 1000.0;
  ReplayAcquisition replay(s, o);
  const CanAcquisitionOptions can = ReplayCanOptions(replay);
  EXPECT_EQ(can.sample_rate, 200000.0);
  EXPECT_TRUE(can.layout.fd);
  Receiver receiver(can);
  SendReplay(replay, UdpCanTransport::Connect("127.0.0.1", receiver.port), can);
  receiver.Join();
  const AcquisitionStats& stats = receiver.acquisition->stats();
  EXPECT_EQ(stats.lost_sample_sets, 0u);
  EXPECT_EQ(stats.corrupt_frames, 0u);
  for (std::size_t c = 0; c < 3; ++c) {
    ASSERT_EQ(receiver.counts[c].size(), static_cast<std::size_t>(n)) << c;
    EXPECT_EQ(receiver.counts[c], replay.counts(0, c)) << c;
  }
  o.speed = 0.0;  // as fast as possible: no rate a receiver could check the frames against
  ReplayAcquisition fastest(s, o);
  EXPECT_THROW(ReplayCanOptions(fastest), std::invalid_argument);
}

TEST(ReplayCli, SendsToAUdpReceiverAndPrintsTheCalibrationItUses) {
  TempDir dir;
  const std::string session = RecordedSession(dir);
  ReplayOptions o;
  o.speed = 10.0;
  ReplayAcquisition probe(ReadSession(session), o);
  Receiver receiver(ReplayCanOptions(probe));
  const test::CommandResult r =
      RunStrut(fmt::format("replay {} --to udp:127.0.0.1:{} --speed 10", session, receiver.port));
  receiver.Join();
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("2000 Hz"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(" at 10x: "), std::string::npos) << r.output;  // the pace (ReplayOptions::pace)
  EXPECT_NE(r.output.find("classic CAN"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("channel force"), std::string::npos) << r.output;
  ASSERT_EQ(receiver.counts[0].size(), 650u);
  EXPECT_EQ(receiver.counts[1][0], probe.counts(0, 1)[0]);
  EXPECT_EQ(receiver.counts[1].back(), probe.counts(2, 1).back());
}

TEST(ReplayCli, PrintsTheSteadyStateOfTheStreamAndOfTheCyclesTheRunnerStored) {
  TempDir dir;
  const std::string recorded = RecordedSession(dir);
  // The session as the matrix runner leaves it: every cycle it saw, settling included.
  Session s = ReadSession(recorded);
  std::vector<rig::CycleSummary> cycles;
  for (long k = 0; k < 80; ++k) {  // 40 s: past the steady-state test's 30 s drift window
    const double settle = std::exp(-0.9 * k);  // settles after a few cycles
    cycles.push_back({k, k * 500'000'000, (k + 1) * 500'000'000 - 5'000'000, 0.005 - 0.002 * settle, 0.025,
                      -9000.0 * (1 + settle), 9000.0, 1.7e6});
  }
  const rig::SteadyStateVerdict expected = rig::DetectSteadyState(cycles, {});
  ASSERT_TRUE(expected.steady);
  s.metadata.push_back({"rig_run", {}, {rig::CyclesGroup("a", cycles, expected, {})}});
  const std::string path = dir.file("run.h5");
  WriteSession(path, s);
  const test::CommandResult r = RunStrut("replay " + path);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("replay " + path + " as fast as possible"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(fmt::format("the runner's cycles (/rig_run/a): steady yes ({} cycles, from cycle {})",
                                      expected.cycles, expected.steady_at)),
            std::string::npos)
      << r.output;
  const rig::SteadyStateVerdict stream = rig::DetectSteadyState(rig::SummariseExperiment(s.experiment("a")), {});
  EXPECT_NE(r.output.find(fmt::format("{} ({} cycles)", stream.steady ? "yes" : "no", stream.cycles)),
            std::string::npos)
      << r.output;
  EXPECT_EQ(stream.cycles, 3);  // 300 samples of 100 per cycle
}

TEST(ReplayCli, BadInputIsAClearErrorNamingTheFileOrOption) {
  TempDir dir;
  const std::string session = RecordedSession(dir);
  const std::string missing = dir.file("missing.h5");
  test::CommandResult r = RunStrut("replay " + missing + " -o " + dir.file("x.h5"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find(missing), std::string::npos) << r.output;

  // A file that fails the contract check: named with what is wrong.
  const std::string broken = dir.file("broken.h5");
  fs::copy_file(session, broken);
  const std::string python = test::PythonWithH5py();
  if (!python.empty()) {
    ASSERT_EQ(test::RunPython(python, dir, "import sys, h5py\nwith h5py.File(sys.argv[1], 'a') as h:\n    del h['experiments/a/force']\n", broken), 0);
    r = RunStrut("replay " + broken + " -o " + dir.file("y.h5"));
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_NE(r.output.find(broken), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("force"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(dir.file("y.h5")));
  }

  for (const char* speed : {"0", "-2", "fast", "nan"}) {
    r = RunStrut("replay " + session + " --speed " + speed);
    EXPECT_EQ(r.exit_code, 1) << speed;
    EXPECT_NE(r.output.find(std::string("--speed ") + speed), std::string::npos) << r.output;
  }

  // Never over the input, never over an existing file without --force.
  const auto size = fs::file_size(session);
  r = RunStrut("replay " + session + " -o " + session + " --force");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("input"), std::string::npos) << r.output;
  EXPECT_EQ(fs::file_size(session), size);
  const std::string existing = dir.file("existing.h5");
  { std::ofstream(existing) << "mine"; }
  r = RunStrut("replay " + session + " -o " + existing);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("--force"), std::string::npos) << r.output;
  EXPECT_EQ(test::ReadFile(existing), "mine");
  r = RunStrut("replay " + session + " -o " + existing + " --force");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  ExpectSameSamples(ReadSession(session), ReadSession(existing));

  r = RunStrut("replay " + session + " -o " + dir.file("z.h5") + " --to udp:127.0.0.1:9");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("--to"), std::string::npos) << r.output;
  r = RunStrut("replay " + session + " --to udp:127.0.0.1:9 --speed max");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("--speed max with --to"), std::string::npos) << r.output;
  r = RunStrut("replay " + session + " --to tcp:nowhere");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("tcp:nowhere"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace strut::daq
