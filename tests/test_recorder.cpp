// The streaming recorder (daq/recorder.h, docs/recording.md): what it records reads back sample
// for sample and passes the contract check (also in h5py); bad calls get errors naming the
// experiment and channel; a full disk or a slow one ends in a clear failure with the data kept;
// a power cut (simulated by keeping only what was synced) and kill -9 (a real child process, 100
// times) lose at most what the durability bound allows, and `strut recover` turns every cut-off
// journal into a valid session.
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <random>
#include <sstream>
#include <thread>

#include "strut/daq/recorder.h"
#include "strut/daq/session.h"
#include "test_support.h"
#include "python_peer.h"

extern char** environ;

namespace strut::daq {
namespace {

using strut::test::PythonWithH5py;
using strut::test::RunPython;
using strut::test::RunStrut;
using strut::test::TempDir;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

std::int64_t NowNs() {
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);
  return std::int64_t{t.tv_sec} * 1'000'000'000 + t.tv_nsec;
}

RecordingMetadata Metadata() {
  RecordingMetadata m;
  m.damper_serial = "MLG-0042";
  m.rig = "shaker-2";
  m.operator_name = "J. Doe";
  m.matrix = "standard";
  m.limits = {{"stroke_max", 0.25}, {"force_max", 20000.0}};
  m.groups = {{"truth", {{"model", std::string("2dof")}, {"theta1", 1.5}}, {}}};
  return m;
}

// A periodic experiment at 200 Hz, 2 Hz: 100 samples a period; stroke with raw counts.
ExperimentDescriptor Periodic(const std::string& label, long periods = 3) {
  ExperimentDescriptor d;
  Experiment& h = d.header;
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
SampleBlock Block(std::int64_t t0_ns, long first, long n, long g0 = 0) {
  SampleBlock b;
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

TEST(Recorder, ResumeGoesOnRecordingIntoAClosedSessionWhoseJournalWasKept) {
  TempDir dir;
  const std::string path = dir.file("run.h5");
  const std::int64_t t0 = NowNs();
  {
    Recorder r = Recorder::Open(path, Metadata());
    r.BeginExperiment(Periodic("e0"));
    r.Append(Block(t0, 0, 300));
    r.EndExperiment(EndStatus::kComplete);
    r.Close(/*keep_journal=*/true);
  }
  // A valid session now, and the journal stays for the resume.
  ASSERT_TRUE(fs::exists(path));
  ASSERT_TRUE(fs::exists(JournalPath(path)));
  EXPECT_EQ(ReadSession(path).experiments.size(), 1u);
  // A new recording into the same path is refused while the journal is there.
  EXPECT_THROW(Recorder::Open(path, Metadata()), RecorderError);

  Session so_far;
  {
    Recorder r = Recorder::Resume(path, {}, "resumed by the test", &so_far);
    ASSERT_EQ(so_far.experiments.size(), 1u);
    EXPECT_EQ(so_far.experiments[0].label, "e0");
    // Labels already recorded stay taken.
    EXPECT_THROW(r.BeginExperiment(Periodic("e0")), RecorderError);
    r.BeginExperiment(Periodic("e1", 2));
    r.Append(Block(t0 + 10'000'000'000, 0, 200, 1000));
    r.EndExperiment(EndStatus::kComplete);
    r.AddMetadata({"rig_run", {{"note", std::string("first")}}, {{"e1", {{"cycles", 2LL}}, {}}}});
    r.AddMetadata({"rig_run", {{"note", std::string("second")}}, {{"e0", {{"cycles", 3LL}}, {}}}});
    EXPECT_THROW(r.AddMetadata({"recording", {}, {}}), RecorderError);
    r.Close();
  }
  EXPECT_FALSE(fs::exists(JournalPath(path)));
  const Session s = ReadSession(path);
  ASSERT_EQ(s.experiments.size(), 2u);
  EXPECT_EQ(s.experiments[0].label, "e0");
  EXPECT_EQ(s.experiments[0].sample_count(), 300u);
  EXPECT_EQ(s.experiments[1].label, "e1");
  EXPECT_EQ(s.experiments[1].sample_count(), 200u);
  EXPECT_DOUBLE_EQ(s.experiments[1].channel("force").samples[5], 1005.0);
  bool resumed = false;
  for (const auto& [kind, text] : strut::test::SessionEvents(s)) resumed |= kind == "resumed" && text == "resumed by the test";
  EXPECT_TRUE(resumed);
  EXPECT_EQ(*s.find_metadata("recording")->text("ended"), "closed");
  // Metadata groups added during the recording are merged by name.
  const MetadataGroup* rig = s.find_metadata("rig_run");
  ASSERT_NE(rig, nullptr);
  EXPECT_EQ(*rig->text("note"), "second");
  ASSERT_EQ(rig->groups.size(), 2u);
  EXPECT_EQ(*rig->find_group("e0")->number("cycles"), 3.0);
  EXPECT_EQ(*rig->find_group("e1")->number("cycles"), 2.0);
}

TEST(Recorder, ResumeAfterACutEndsTheExperimentInProgressAbortedAndCutsTheTornTail) {
  TempDir dir;
  const std::string path = dir.file("cut.h5");
  const std::string copy = dir.file("copy.h5");
  const std::int64_t t0 = NowNs();
  RecorderOptions options;
  options.sync_interval = std::chrono::milliseconds(5);
  {
    Recorder r = Recorder::Open(path, Metadata(), options);
    r.BeginExperiment(Periodic("e0"));
    r.Append(Block(t0, 0, 300));
    r.EndExperiment(EndStatus::kComplete);
    r.BeginExperiment(Periodic("e1"));
    r.Append(Block(t0 + 5'000'000'000, 0, 120));
    // What a kill -9 leaves: the journal as written so far, plus half a record of garbage.
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    fs::copy_file(JournalPath(path), JournalPath(copy));
    std::ofstream(JournalPath(copy), std::ios::app | std::ios::binary) << std::string("\x40\x00\x00\x00\x03\x00", 6);
    r.Close();
  }
  {
    Recorder r = Recorder::Resume(copy, options);
    r.BeginExperiment(Periodic("e1-2"));
    r.Append(Block(t0 + 9'000'000'000, 0, 300));
    r.EndExperiment(EndStatus::kComplete);
    r.Close();
  }
  const Session s = ReadSession(copy);
  ASSERT_EQ(s.experiments.size(), 3u);
  EXPECT_EQ(s.experiments[0].status, "complete");
  EXPECT_EQ(s.experiments[1].label, "e1");
  EXPECT_EQ(s.experiments[1].status, "aborted");
  EXPECT_EQ(s.experiments[1].sample_count(), 120u);
  EXPECT_EQ(s.experiments[1].extra_attributes.at("requested_periods"), "3");
  EXPECT_EQ(s.experiments[2].label, "e1-2");
  EXPECT_EQ(s.experiments[2].status, "complete");
  int recovered = 0;
  for (const auto& [kind, text] : strut::test::SessionEvents(s)) recovered += kind == "recovered" && text.find("'e1'") != std::string::npos;
  EXPECT_EQ(recovered, 1);
  // Without a journal there is nothing to resume.
  EXPECT_THROW(Recorder::Resume(dir.file("none.h5")), RecorderError);
}

TEST(Recorder, RoundTripGivesBackEverySampleEventAndCalibration) {
  TempDir dir;
  const std::string path = dir.file("run.h5");
  const std::int64_t t0 = 5'000'000'000;
  {
    Recorder r = Recorder::Open(path, Metadata());
    EXPECT_TRUE(fs::exists(r.journal_path()));
    EXPECT_FALSE(fs::exists(path));
    r.BeginExperiment(Periodic("a"));
    for (long i = 0; i < 300; i += 64) r.Append(Block(t0, i, std::min(64L, 300 - i)));
    r.Event(t0 + 100 * 5'000'000, "pause", "operator pause");
    r.EndExperiment(EndStatus::kComplete);
    ExperimentDescriptor b = Periodic("b", 4);
    r.BeginExperiment(b);
    r.Append(Block(t0 + 10'000'000'000, 0, 150, 300));
    r.Event(t0 + 10'000'000'000 + 149 * 5'000'000, "trip", "force limit 20 kN");
    r.EndExperiment(EndStatus::kAborted);
    EXPECT_EQ(r.stats().samples, 450u);
    r.Close();
    EXPECT_FALSE(fs::exists(r.journal_path()));
  }
  const Session s = ReadSession(path);
  EXPECT_EQ(s.damper_serial, "MLG-0042");
  EXPECT_EQ(s.rig, "shaker-2");
  ASSERT_EQ(s.experiments.size(), 2u);
  const Experiment& a = s.experiment("a");
  EXPECT_EQ(a.status, "complete");
  EXPECT_EQ(a.periods, 3);
  EXPECT_EQ(a.group, "high");
  EXPECT_EQ(a.extra_attributes.at("note"), "first try");
  EXPECT_EQ(a.extra_attributes.at("recording_end"), "complete");
  EXPECT_EQ(a.extra_attributes.at("monotonic_start_ns"), std::to_string(t0));
  const SampleBlock expected = Block(t0, 0, 300);
  ASSERT_EQ(a.sample_count(), 300u);
  for (std::size_t i = 0; i < 300; ++i) {
    ASSERT_EQ(a.time[i], static_cast<double>(expected.monotonic_ns[i] - t0) / 1e9) << i;
    ASSERT_EQ(a.channel("stroke").samples[i], expected.values[0][i]) << i;
    ASSERT_EQ(a.channel("force").samples[i], expected.values[1][i]) << i;
    ASSERT_EQ(a.channel("pressure").samples[i], expected.values[2][i]) << i;
    ASSERT_EQ(a.channel("stroke_counts").samples[i], expected.counts[0][i]) << i;
    ASSERT_EQ(a.channel("sequence").samples[i], static_cast<double>(i)) << i;
  }
  EXPECT_EQ(a.channel("status").samples[7], 4.0);
  EXPECT_EQ(a.channel("stroke_counts").units, "1");
  EXPECT_EQ(a.channel("pressure").reference, "gauge");

  const Experiment& b = s.experiment("b");
  EXPECT_EQ(b.status, "aborted");
  EXPECT_EQ(b.periods, 0);
  EXPECT_EQ(b.extra_attributes.at("requested_periods"), "4");
  EXPECT_EQ(b.extra_attributes.at("recording_end"), "aborted");
  EXPECT_EQ(b.sample_count(), 150u);
  EXPECT_EQ(b.channel("force").samples.back(), 449.0);

  const MetadataGroup* recording = s.find_metadata("recording");
  ASSERT_NE(recording, nullptr);
  EXPECT_EQ(recording->text("operator"), "J. Doe");
  EXPECT_EQ(recording->text("matrix"), "standard");
  EXPECT_EQ(recording->text("ended"), "closed");
  EXPECT_EQ(recording->text("software_version"), "strut 0.1.0");
  EXPECT_EQ(recording->find_group("limits")->number("stroke_max"), 0.25);
  const MetadataGroup* cal = recording->find_group("calibration")->find_group("a")->find_group("stroke");
  ASSERT_NE(cal, nullptr);
  EXPECT_EQ(cal->number("gain"), 1e-6);
  EXPECT_EQ(cal->text("counts_channel"), "stroke_counts");
  const MetadataGroup* events = recording->find_group("events");
  ASSERT_NE(events, nullptr);
  ASSERT_EQ(events->groups.size(), 2u);
  EXPECT_EQ(events->groups[0].text("kind"), "pause");
  EXPECT_EQ(events->groups[0].text("experiment"), "a");
  EXPECT_NEAR(*events->groups[0].number("time"), 0.5, 1e-12);
  EXPECT_EQ(events->groups[1].text("kind"), "trip");
  EXPECT_EQ(events->groups[1].text("text"), "force limit 20 kN");
  EXPECT_EQ(events->groups[1].text("experiment"), "b");
  EXPECT_FALSE(recording->find_group("clock")->groups.empty());
  EXPECT_NE(s.find_metadata("truth"), nullptr);
  EXPECT_EQ(s.find_metadata("truth")->number("theta1"), 1.5);
}

TEST(Recorder, AnAcquiredStreamIsRecordedWithItsCountsIndicesAndQuality) {
  // A stream of three channels at 100 Hz; the recorder keeps a slice of each acquired block.
  StreamDescription stream{"udp:test module 1", 100.0,
                           {{"stroke", "m", Calibration::FromRange16(-0.05, 0.35)},
                            {"force", "N", Calibration::FromRange16(-5e4, 5e4)},
                            {"pressure", "Pa", Calibration::FromRange16(0.0, 2e7)}}};
  Experiment header;
  header.label = "a";
  header.frequency = 1.0;
  header.amplitude = 0.01;
  header.static_position = 0.15;
  header.periods = 1;
  const ExperimentDescriptor d = AcquiredExperiment(header, stream);
  EXPECT_EQ(d.header.sample_rate, 100.0);
  ASSERT_EQ(d.header.channels.size(), 3u);
  EXPECT_EQ(d.header.channels[2].reference, "gauge");
  EXPECT_EQ(d.header.channels[0].reference, "");
  ASSERT_EQ(d.raw.size(), 3u);
  EXPECT_EQ(d.raw[2].calibration.gain, stream.channels[2].calibration.gain);

  // Blocks of 30 sample sets from index 20 on; the second one flagged with a bus error.
  const auto acquired = [&](std::uint64_t first, std::uint32_t flags) {
    AcquiredBlock b;
    b.first_index = first;
    b.quality.flags = flags;
    b.counts.assign(3, {});
    b.values.assign(3, {});
    for (std::uint64_t i = first; i < first + 30; ++i) {
      b.time_ns.push_back(1'000'000'000 + static_cast<std::int64_t>(i) * 10'000'000);
      for (int c = 0; c < 3; ++c) {
        const auto counts = static_cast<std::int32_t>(i * 100) - 5000 * c;
        b.counts[c].push_back(counts);
        b.values[c].push_back(stream.channels[c].calibration.ToSi(counts));
      }
    }
    return b;
  };
  const AcquiredBlock first = acquired(20, 0), second = acquired(50, Quality::kBusErrors);
  EXPECT_TRUE(RecordedBlock(first, 40).monotonic_ns.empty());
  TempDir dir;
  const std::string path = dir.file("acquired.h5");
  {
    Recorder r = Recorder::Open(path, Metadata());
    r.BeginExperiment(d);
    r.Append(RecordedBlock(first, 10));          // indices 30..49
    r.Append(RecordedBlock(second, 0, 70));     // 50..79 (end clipped to the block)
    r.Append(RecordedBlock(acquired(80, 0), 0, 10));  // 80..89
    r.EndExperiment(EndStatus::kAborted);
    r.Close();
  }
  const Experiment e = ReadSession(path).experiment("a");
  ASSERT_EQ(e.sample_count(), 60u);
  for (std::size_t k = 0; k < 60; ++k) {
    const std::uint64_t index = 30 + k;
    ASSERT_EQ(e.channel("sequence").samples[k], static_cast<double>(index)) << k;
    ASSERT_EQ(e.channel("pressure_counts").samples[k], static_cast<double>(index * 100) - 10000) << k;
    ASSERT_EQ(e.channel("pressure").samples[k],
              stream.channels[2].calibration.ToSi(static_cast<std::int32_t>(index * 100) - 10000)) << k;
    ASSERT_EQ(e.channel("status").samples[k], index >= 50 && index < 80 ? double{Quality::kBusErrors} : 0.0) << k;
    ASSERT_NEAR(e.time[k], k * 0.01, 1e-12) << k;
  }
}

TEST(Recorder, RefusesToOverwriteASessionOrAJournalUnlessForced) {
  TempDir dir;
  const std::string path = dir.file("run.h5");
  std::ofstream(path) << "precious";
  try {
    Recorder::Open(path, Metadata());
    FAIL() << "overwrote an existing file";
  } catch (const RecorderError& e) {
    EXPECT_NE(std::string(e.what()).find(path + ": exists"), std::string::npos) << e.what();
  }
  EXPECT_EQ(test::ReadFile(path), "precious");
  fs::remove(path);
  std::ofstream(JournalPath(path)) << "left over";
  try {
    Recorder::Open(path, Metadata());
    FAIL() << "overwrote a journal";
  } catch (const RecorderError& e) {
    EXPECT_NE(std::string(e.what()).find("strut recover"), std::string::npos) << e.what();
  }
  EXPECT_EQ(test::ReadFile(JournalPath(path)), "left over");
  RecorderOptions force;
  force.force = true;
  Recorder r = Recorder::Open(path, Metadata(), force);
  r.BeginExperiment(Periodic("a", 1));
  r.Append(Block(0, 0, 100));
  r.EndExperiment(EndStatus::kComplete);
  r.Close();
  EXPECT_EQ(ReadSession(path).experiment("a").sample_count(), 100u);
}

// The message of the RecorderError `call` throws ("" when it does not throw).
template <typename F>
std::string ErrorOf(F call) {
  try {
    call();
  } catch (const RecorderError& e) {
    return e.what();
  }
  return "";
}

TEST(Recorder, BadCallsGetErrorsNamingTheExperimentAndChannel) {
  TempDir dir;
  const std::string path = dir.file("run.h5");
  EXPECT_NE(ErrorOf([&] { Recorder::Open(path, {"", "rig", "", "", "", {}, "damper", {}}); }).find("damper_serial"),
            std::string::npos);
  RecorderOptions slow;
  slow.sync_interval = std::chrono::milliseconds(5000);
  EXPECT_NE(ErrorOf([&] { Recorder::Open(path, Metadata(), slow); }).find("sync_interval"), std::string::npos);
  EXPECT_FALSE(fs::exists(JournalPath(path)));

  Recorder r = Recorder::Open(path, Metadata());
  EXPECT_NE(ErrorOf([&] { r.Append(Block(0, 0, 10)); }).find("no experiment open"), std::string::npos);
  ExperimentDescriptor bad = Periodic("x");
  bad.header.channels[1].units = "kN";
  const std::string units = ErrorOf([&] { r.BeginExperiment(bad); });
  EXPECT_NE(units.find("experiment 'x'"), std::string::npos) << units;
  EXPECT_NE(units.find("channel 'force': attribute 'units'"), std::string::npos) << units;
  ExperimentDescriptor raw = Periodic("y");
  raw.raw[0].channel = "temperature";
  EXPECT_NE(ErrorOf([&] { r.BeginExperiment(raw); }).find("'temperature', which is not a channel"), std::string::npos);

  r.BeginExperiment(Periodic("a"));
  EXPECT_NE(ErrorOf([&] { r.BeginExperiment(Periodic("b")); }).find("while 'a' is open"), std::string::npos);
  SampleBlock short_force = Block(0, 0, 10);
  short_force.values[1].pop_back();
  const std::string size = ErrorOf([&] { r.Append(short_force); });
  EXPECT_NE(size.find("experiment 'a': channel 'force': 9 samples in a block of 10"), std::string::npos) << size;
  SampleBlock nan = Block(0, 0, 10);
  nan.values[2][4] = std::nan("");
  EXPECT_NE(ErrorOf([&] { r.Append(nan); }).find("channel 'pressure': NaN/Inf at sample 4"), std::string::npos);
  r.Append(Block(0, 0, 50));
  const std::string back = ErrorOf([&] { r.Append(Block(0, 40, 10)); });
  EXPECT_NE(back.find("timestamps not increasing at sample 50"), std::string::npos) << back;
  const std::string gap = ErrorOf([&] { r.Append(Block(0, 52, 10)); });  // samples 50 and 51 lost
  EXPECT_NE(gap.find("sample 50 comes 15000000 ns after the previous one"), std::string::npos) << gap;
  const std::string count = ErrorOf([&] { r.EndExperiment(EndStatus::kComplete); });
  EXPECT_NE(count.find("experiment 'a': cannot end it complete: 50 samples, but periods"), std::string::npos) << count;
  EXPECT_NE(ErrorOf([&] { r.EndExperiment(EndStatus::kNotSteady, 1); }).find("50 samples"), std::string::npos);
  r.EndExperiment(EndStatus::kAborted);
  r.BeginExperiment(Periodic("c", 1));
  EXPECT_NE(ErrorOf([&] { r.BeginExperiment(Periodic("a")); }).find("open"), std::string::npos);
  r.Append(Block(1'000'000'000, 0, 100));
  r.EndExperiment(EndStatus::kNotSteady);
  EXPECT_NE(ErrorOf([&] { r.BeginExperiment(Periodic("c")); }).find("'c' was recorded already"), std::string::npos);
  EXPECT_NE(ErrorOf([&] { r.Event(0, "", "x"); }).find("needs a kind"), std::string::npos);
  r.Close();
  EXPECT_NE(ErrorOf([&] { r.Append(Block(0, 0, 1)); }).find("closed"), std::string::npos);
  const Session s = ReadSession(path);
  EXPECT_EQ(s.experiment("a").status, "aborted");
  EXPECT_EQ(s.experiment("a").extra_attributes.at("requested_periods"), "3");
  EXPECT_EQ(s.experiment("c").status, "complete");
  EXPECT_EQ(s.experiment("c").extra_attributes.at("recording_end"), "not-steady");
}

TEST(Recorder, NaNInFieldsAStaticExperimentDoesNotUseReadsBack) {
  // JSON has no NaN: the journal stores null, and the reader must not take that for damage.
  TempDir dir;
  const std::string path = dir.file("run.h5");
  {
    Recorder r = Recorder::Open(path, Metadata());
    ExperimentDescriptor d = Periodic("s");
    d.header.kind = ExperimentKind::kStatic;
    d.header.frequency = std::nan("");
    d.raw[0].calibration.range_max = std::nan("");
    r.BeginExperiment(d);
    r.Append(Block(0, 0, 20));
    r.EndExperiment(EndStatus::kComplete);
  }
  const Session s = ReadSession(path);
  EXPECT_EQ(s.experiment("s").kind, ExperimentKind::kStatic);
  EXPECT_EQ(s.experiment("s").sample_count(), 20u);
}

// A journal sink that writes the real file and logs each sync (time, bytes durable), and can
// fail (disk full, after `fail_after` bytes, writing part of the record first) or be slow.
class FakeSink final : public JournalSink {
 public:
  struct Synced {
    Clock::time_point at;
    std::uint64_t bytes;
  };
  FakeSink(const std::string& journal, std::uint64_t fail_after = UINT64_MAX,
           std::chrono::milliseconds delay = std::chrono::milliseconds(0))
      : file_(CreateJournalFile(journal, false)), fail_after_(fail_after), delay_(delay) {}

  void Write(std::span<const std::byte> bytes) override {
    if (delay_.count() > 0) std::this_thread::sleep_for(delay_);
    if (written_ + bytes.size() > fail_after_) {
      file_->Write(bytes.first(static_cast<std::size_t>(fail_after_ - written_)));  // a torn record
      written_ = fail_after_;
      throw RecorderError("fake.journal: cannot write: writing: No space left on device");
    }
    file_->Write(bytes);
    written_ += bytes.size();
  }
  void Sync() override {
    file_->Sync();
    std::lock_guard lock(mutex_);
    syncs_.push_back({Clock::now(), written_});
  }
  void Close() override { file_->Close(); }

  std::vector<Synced> syncs() const {
    std::lock_guard lock(mutex_);
    return syncs_;
  }

 private:
  std::unique_ptr<JournalSink> file_;
  std::uint64_t fail_after_;
  std::chrono::milliseconds delay_;
  std::uint64_t written_ = 0;
  mutable std::mutex mutex_;
  std::vector<Synced> syncs_;
};

// Copies the first `bytes` of `from` to `to`: what a power cut would have left on the disk.
void CopyPrefix(const std::string& from, const std::string& to, std::uint64_t bytes) {
  std::ifstream in(from, std::ios::binary);
  std::vector<char> data(bytes);
  in.read(data.data(), static_cast<std::streamsize>(bytes));
  std::ofstream(to, std::ios::binary).write(data.data(), in.gcount());
}

TEST(Recorder, APowerCutLosesOnlyWhatWasHandedOverWithinTheSyncInterval) {
  TempDir dir;
  const std::string path = dir.file("run.h5");
  RecorderOptions options;
  options.sync_interval = std::chrono::milliseconds(100);
  auto sink = std::make_unique<FakeSink>(JournalPath(path));
  FakeSink* fake = sink.get();
  struct Handed {
    Clock::time_point at;
    long samples;
  };
  std::vector<Handed> handed;
  std::vector<FakeSink::Synced> syncs;
  {
    Recorder r = Recorder::Open(path, Metadata(), options, std::move(sink));
    // 1.2 s of a 200 Hz experiment handed over in real time, 10 samples (50 ms) a block.
    r.BeginExperiment(Periodic("a", 12));
    const auto start = Clock::now();
    for (long i = 0; i < 1200; i += 10) {
      std::this_thread::sleep_until(start + std::chrono::milliseconds(i));
      r.Append(Block(0, i, 10));
      handed.push_back({Clock::now(), i + 10});
    }
    EXPECT_LE(r.stats().longest_sync_gap_s, 0.1 + 0.4) << "written data waited too long for a sync";
    // Keep the journal as it is before Close converts and removes it.
    while (r.stats().bytes_synced < r.stats().bytes_handed) std::this_thread::sleep_for(std::chrono::milliseconds(5));
    fs::copy_file(r.journal_path(), dir.file("full.journal"));
    syncs = fake->syncs();  // the recorder owns the sink: read it while the recorder lives
    r.EndExperiment(EndStatus::kComplete);
  }
  ASSERT_GE(syncs.size(), 8u);  // 1.2 s at 100 ms
  // Cut the power at 40 moments: keep what the last sync before it made durable.
  const double bound = 0.1 + 0.4;  // sync interval + slack for a loaded machine, inside the promised 1 s
  int cuts = 0;
  for (auto at = handed.front().at; at < handed.back().at; at += std::chrono::milliseconds(30)) {
    std::uint64_t durable = 0;
    for (const auto& s : syncs)
      if (s.at <= at) durable = s.bytes;
    CopyPrefix(dir.file("full.journal"), dir.file("cut.journal"), durable);
    JournalReport report;
    const Session s = ReadJournal(dir.file("cut.journal"), &report);
    long kept = 0;
    for (const Experiment& e : s.experiments) kept += static_cast<long>(e.sample_count());
    long owed = 0;  // handed over at least `bound` before the cut
    for (const Handed& h : handed)
      if (h.at <= at - std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(bound))) owed = h.samples;
    EXPECT_GE(kept, owed) << "cut at " << std::chrono::duration<double>(at - handed.front().at).count() << " s";
    if (kept > 0) {
      EXPECT_EQ(s.experiments[0].status, "aborted");
      EXPECT_TRUE(Validate(s).empty());
    }
    ++cuts;
  }
  EXPECT_GE(cuts, 30);
  EXPECT_EQ(ReadSession(path).experiment("a").sample_count(), 1200u);
}

// Records experiment a (100 samples, complete) and `b_samples` of b in blocks of `block`, with a
// trip event, and copies the journal to `copy` as a crash at that moment would have left it.
void RecordCutOff(const std::string& path, const std::string& copy, long b_samples, long block) {
  Recorder r = Recorder::Open(path, Metadata());
  r.BeginExperiment(Periodic("a", 1));
  r.Append(Block(0, 0, 100));
  r.EndExperiment(EndStatus::kComplete);
  r.BeginExperiment(Periodic("b", 2));
  for (long i = 0; i < b_samples; i += block) r.Append(Block(1'000'000'000, i, block, 100));
  r.Event(1'000'000'000, "trip", "stroke limit");
  while (r.stats().bytes_written < r.stats().bytes_handed) std::this_thread::sleep_for(std::chrono::milliseconds(2));
  fs::copy_file(r.journal_path(), copy);
}

TEST(Recorder, ATornOrDamagedJournalIsReadUpToItsLastIntactRecord) {
  TempDir dir;
  const std::string path = dir.file("run.h5");
  RecordCutOff(path, dir.file("full.journal"), 200, 20);
  const std::uint64_t size = fs::file_size(dir.file("full.journal"));
  long previous = -1;
  const auto level = spdlog::get_level();
  spdlog::set_level(spdlog::level::err);  // one warning per cut about the discarded tail
  for (std::uint64_t at = 300;; at += 97) {  // every few bytes: mid-record tears, then the whole journal
    const std::uint64_t cut = std::min(at, size);
    CopyPrefix(dir.file("full.journal"), dir.file("cut.journal"), cut);
    JournalReport report;
    Session s;
    try {
      s = ReadJournal(dir.file("cut.journal"), &report);
    } catch (const RecorderError& e) {  // only while the header record itself is cut
      EXPECT_EQ(previous, -1) << e.what();
      EXPECT_NE(std::string(e.what()).find("nothing to recover"), std::string::npos) << e.what();
      continue;
    }
    EXPECT_EQ(report.bytes_read + report.bytes_discarded, cut);
    long kept = 0;
    for (const Experiment& e : s.experiments) {
      kept += static_cast<long>(e.sample_count());
      for (std::size_t i = 0; i < e.sample_count(); ++i) ASSERT_EQ(e.channel("force").samples[i], (e.label == "a" ? 0 : 100) + static_cast<double>(i));
    }
    EXPECT_GE(kept, previous);  // a longer journal never holds fewer samples
    previous = kept;
    EXPECT_TRUE(Validate(s).empty()) << "cut at " << cut;
    if (cut == size) break;
  }
  spdlog::set_level(level);
  EXPECT_EQ(previous, 300);
  // A flipped byte in the middle of the second experiment's samples: the checksum stops there.
  std::string bytes = test::ReadFile(dir.file("full.journal"));
  bytes[bytes.size() - 500] ^= 0x10;
  std::ofstream(dir.file("flipped.journal"), std::ios::binary) << bytes;
  JournalReport report;
  const Session s = ReadJournal(dir.file("flipped.journal"), &report);
  EXPECT_GT(report.bytes_discarded, 0u);
  EXPECT_LT(s.experiment("b").sample_count(), 200u);
  EXPECT_EQ(s.experiment("a").sample_count(), 100u);
  EXPECT_EQ(s.experiment("a").status, "complete");
  // Not a journal at all, and a session file given by mistake.
  std::ofstream(dir.file("text.journal")) << "hello";
  EXPECT_NE(ErrorOf([&] { ReadJournal(dir.file("text.journal")); }).find("not a strut recording journal"),
            std::string::npos);
  EXPECT_NE(ErrorOf([&] { ReadJournal(path); }).find("is an HDF5 file, not a recording journal"), std::string::npos);
  CopyPrefix(dir.file("full.journal"), dir.file("header.journal"), 20);
  EXPECT_NE(ErrorOf([&] { ReadJournal(dir.file("header.journal")); }).find("nothing to recover"), std::string::npos);
}

TEST(Recorder, AFullDiskFailsTheRecordingClearlyAndKeepsWhatWasWritten) {
  TempDir dir;
  const std::string path = dir.file("run.h5");
  auto sink = std::make_unique<FakeSink>(JournalPath(path), 20000);
  Recorder r = Recorder::Open(path, Metadata(), {}, std::move(sink));
  r.BeginExperiment(Periodic("a", 10));
  std::string error;
  for (long i = 0; i < 1000 && error.empty(); i += 20) {
    error = ErrorOf([&] { r.Append(Block(0, i, 20)); });
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  EXPECT_NE(error.find("recording failed"), std::string::npos) << error;
  EXPECT_NE(error.find("No space left on device"), std::string::npos) << error;
  EXPECT_NE(ErrorOf([&] { r.Event(0, "note", "x"); }).find("No space left"), std::string::npos);
  const std::string closed = ErrorOf([&] { r.Close(); });
  EXPECT_NE(closed.find("holds what was recorded until then"), std::string::npos) << closed;
  const Session s = ReadSession(path);
  EXPECT_EQ(s.experiment("a").status, "aborted");
  EXPECT_GT(s.experiment("a").sample_count(), 100u);
  EXPECT_TRUE(fs::exists(JournalPath(path)));  // kept after a failure
}

TEST(Recorder, AFullQueueRefusesTheBlockInsteadOfDroppingItSilently) {
  TempDir dir;
  const std::string path = dir.file("run.h5");
  RecorderOptions options;
  options.queue_limit_bytes = 4096;
  options.queue_full_timeout = std::chrono::milliseconds(50);
  auto sink = std::make_unique<FakeSink>(JournalPath(path), UINT64_MAX, std::chrono::milliseconds(200));
  Recorder r = Recorder::Open(path, Metadata(), options, std::move(sink));
  r.BeginExperiment(Periodic("a", 10));
  std::string error;
  long handed = 0;
  for (long i = 0; i < 1000 && error.empty(); i += 20) {
    error = ErrorOf([&] { r.Append(Block(0, i, 20)); });
    if (error.empty()) handed = i + 20;
  }
  EXPECT_NE(error.find("could not keep up"), std::string::npos) << error;
  EXPECT_NE(ErrorOf([&] { r.Append(Block(0, 1000, 20)); }).find("could not keep up"), std::string::npos);
  EXPECT_NE(ErrorOf([&] { r.Close(); }).find("holds what was recorded"), std::string::npos);
  // Every block accepted before the failure is in the file, and nothing after it.
  EXPECT_EQ(static_cast<long>(ReadSession(path).experiment("a").sample_count()), handed);
}

TEST(Recorder, StrutRecoverWritesAValidSessionAndLeavesTheJournalAlone) {
  TempDir dir;
  const std::string path = dir.file("run.h5");
  RecordCutOff(path, dir.file("cut.h5.journal"), 120, 120);
  const std::string journal = dir.file("cut.h5.journal");
  const std::string before = test::ReadFile(journal);
  auto result = RunStrut("recover " + journal);
  ASSERT_EQ(result.exit_code, 0) << result.output;
  EXPECT_NE(result.output.find("cut off"), std::string::npos) << result.output;
  EXPECT_EQ(test::ReadFile(journal), before);
  const Session s = ReadSession(dir.file("cut.h5"));
  EXPECT_EQ(s.experiment("a").status, "complete");
  EXPECT_EQ(s.experiment("b").status, "aborted");
  EXPECT_EQ(s.experiment("b").sample_count(), 120u);
  EXPECT_EQ(s.find_metadata("recording")->text("ended"), "recovered");
  const MetadataGroup* events = s.find_metadata("recording")->find_group("events");
  ASSERT_NE(events, nullptr);
  EXPECT_EQ(events->groups.back().text("kind"), "recovered");

  result = RunStrut("recover " + journal);  // the output exists now
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_NE(result.output.find("--force"), std::string::npos) << result.output;
  // The session's name finds its journal; --delete-journal is the only way the input goes away.
  result = RunStrut("recover " + dir.file("cut.h5") + " -o " + dir.file("other.h5"));
  EXPECT_EQ(result.exit_code, 1) << "cut.h5 exists and is no journal: " << result.output;
  fs::rename(dir.file("cut.h5"), dir.file("first.h5"));
  result = RunStrut("recover " + dir.file("cut.h5") + " -o " + dir.file("second.h5") + " --delete-journal");
  ASSERT_EQ(result.exit_code, 0) << result.output;
  EXPECT_FALSE(fs::exists(journal));
  EXPECT_EQ(ReadSession(dir.file("second.h5")).experiment("b").sample_count(), 120u);
  result = RunStrut("recover " + dir.file("second.h5") + " -o " + dir.file("third.h5"));
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_NE(result.output.find("is an HDF5 file, not a recording journal"), std::string::npos) << result.output;
}

TEST(Recorder, H5pyReadsRecordedFilesWithStringsAsStrAndNumbersAsNumbers) {
  const std::string python = PythonWithH5py();
  if (python.empty()) GTEST_SKIP() << "python3 with h5py and numpy not found";
  TempDir dir;
  const std::string path = dir.file("run.h5");
  {
    Recorder r = Recorder::Open(path, Metadata());
    ExperimentDescriptor d = Periodic("a", 1);
    d.header.extra_attributes = {{"count", "7"}, {"gain", "1.5"}, {"serial", "0042"}, {"flag", "true"}, {"sci", "1e3"}};
    r.BeginExperiment(d);
    r.Append(Block(0, 0, 100));
    r.Event(0, "pause", "pause \u00e9");
    r.EndExperiment(EndStatus::kComplete);
    r.Close();
  }
  // The simulator's writer too: its numeric metadata (sim_max_load_fraction) as numbers.
  std::ofstream(dir.file("m.toml")) << "periods = 2\nsample_rate = 200.0\n[[experiment]]\nlabel = \"a\"\n"
                                       "frequency = 2.0\nstatic_position = 0.1\namplitude = 0.02\n";
  ASSERT_EQ(RunStrut("sim matrix --seed 3 --matrix " + dir.file("m.toml") + " -o " + dir.file("sim.h5")).exit_code, 0);
  const char* script = R"(
import sys, h5py, numpy as np
def check_strings(obj, path):
    for k, v in obj.attrs.items():
        assert not isinstance(v, bytes), f"{path}@{k} is bytes: {v!r}"
    if isinstance(obj, h5py.Group):
        for k, child in obj.items():
            check_strings(child, path + "/" + k)
with h5py.File(sys.argv[1], "r") as h:
    check_strings(h, "")
    assert h.attrs["format"] == "damper-session" and isinstance(h.attrs["damper_serial"], str)
    a = h["experiments/a"]
    assert isinstance(a.attrs["kind"], str) and a.attrs["status"] == "complete"
    assert a["stroke"].attrs["units"] == "m" and a["pressure"].attrs["reference"] == "gauge"
    assert a.attrs["count"] == 7 and a.attrs["count"].dtype.kind == "i"
    assert a.attrs["gain"] == 1.5 and a.attrs["gain"].dtype.kind == "f"
    assert a.attrs["serial"] == "0042" and a.attrs["flag"] == "true" and a.attrs["sci"] == "1e3"
    assert a.attrs["monotonic_start_ns"].dtype.kind == "i"
    assert a["force"].dtype == np.float64 and a["force"][99] == 99.0 and a["stroke_counts"].shape == (100,)
    r = h["recording"]
    assert r.attrs["operator"] == "J. Doe" and r["limits"].attrs["stroke_max"] == 0.25
    e = r["events/000000"]
    assert e.attrs["kind"] == "pause" and e.attrs["text"] == "pause \u00e9" and e.attrs["monotonic_ns"].dtype.kind == "i"
    assert isinstance(r["calibration/a/stroke"].attrs["gain"], np.floating)
with h5py.File(sys.argv[2], "r") as h:
    check_strings(h, "")
    g = h["experiments/a"]
    v = g.attrs["sim_max_load_fraction"]
    assert isinstance(v, np.floating), repr(v)
    assert g.attrs["sim_settle_periods"].dtype.kind == "i", repr(g.attrs["sim_settle_periods"])
    assert g.attrs["sim_settled"] == "true" and isinstance(g.attrs["sim_model"], str)
print("h5py types ok")
)";
  EXPECT_EQ(RunPython(python, dir, script, path + " " + dir.file("sim.h5")), 0);
  // Read back by strut: the same texts as were given.
  const Experiment a = ReadSession(path).experiment("a");
  EXPECT_EQ(a.extra_attributes.at("count"), "7");
  EXPECT_EQ(a.extra_attributes.at("gain"), "1.5");
  EXPECT_EQ(a.extra_attributes.at("serial"), "0042");
  EXPECT_EQ(a.extra_attributes.at("sci"), "1e3");
}

// Starts the child recorder; its pid.
pid_t SpawnChild(const std::vector<std::string>& args) {
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  pid_t pid = -1;
  if (posix_spawn(&pid, argv[0], nullptr, nullptr, argv.data(), environ) != 0) return -1;
  return pid;
}

TEST(Recorder, KillNineAtRandomMomentsLosesAtMostTheLastMomentAndRecoverMendsEveryFile) {
  TempDir dir;
  std::mt19937 random(20261202);
  std::uniform_int_distribution<int> delay_ms(10, 700), early_ms(0, 30), experiments(1, 4);
  const int runs = 100;
  // Promised: at most the last second is lost. Under kill -9 only the queue is lost (the page cache
  // keeps every write), so a tighter bound holds and is checked: half a second, which leaves room
  // for a writer thread starved on a loaded machine (178 ms seen at load 17 on 2 cores) and still
  // binds for the runs killed later than that.
  const double bound_s = 0.5;
  int recovered = 0, closed = 0, empty = 0;
  double worst_loss_s = 0.0;
  std::string files;
  for (int run = 0; run < runs; ++run) {
    const std::string session = dir.file(fmt::format("k{:03}.h5", run));
    const std::string report = dir.file(fmt::format("k{:03}.txt", run));
    // 2 kHz on a 10x clock (20,000 samples a wall second), blocks of 50, 4 periods of 2 Hz an
    // experiment, sync every 100 ms.
    const pid_t pid = SpawnChild({STRUT_RECORDER_CHILD, session, report, "2000", "10", "50",
                                  std::to_string(experiments(random)), "4", "2", "100"});
    ASSERT_GT(pid, 0);
    // Every tenth run is killed 0-30 ms after it started (inside Open, most likely); the others at
    // a random moment after the recorder reported it was open.
    if (run % 10 == 0) {
      std::this_thread::sleep_for(std::chrono::milliseconds(early_ms(random)));
    } else {
      const auto give_up = Clock::now() + std::chrono::seconds(10);
      std::error_code ec;
      while ((!fs::exists(report, ec) || fs::file_size(report, ec) == 0) && Clock::now() < give_up)
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      std::this_thread::sleep_for(std::chrono::milliseconds(delay_ms(random)));
    }
    const std::int64_t kill_ns = NowNs();
    kill(pid, SIGKILL);
    int status = 0;
    waitpid(pid, &status, 0);
    ASSERT_TRUE(WIFSIGNALED(status) || (WIFEXITED(status) && WEXITSTATUS(status) == 0)) << "run " << run;

    // What the child had handed over, and when.
    std::ifstream lines(report);
    long handed = 0, owed = 0;
    std::int64_t last_ns = 0;
    std::vector<std::pair<long, std::int64_t>> log;
    for (std::string word; lines >> word;) {
      if (word == "closed") break;
      std::int64_t at = 0;
      lines >> at;
      handed = std::stol(word);
      last_ns = at;
      log.push_back({handed, at});
      if (at <= kill_ns - static_cast<std::int64_t>(bound_s * 1e9)) owed = handed;
    }
    (void)last_ns;
    if (!fs::exists(session)) {
      if (!fs::exists(JournalPath(session))) {
        EXPECT_EQ(handed, 0) << "run " << run << ": samples handed over but neither session nor journal";
        ++empty;
        continue;
      }
      const auto r = RunStrut("recover " + JournalPath(session));
      if (r.exit_code != 0 && handed == 0 && r.output.find("nothing to recover") != std::string::npos) {
        ++empty;  // killed inside Open, before its header record was written
        continue;
      }
      ASSERT_EQ(r.exit_code, 0) << "run " << run << ": " << r.output;
      ++recovered;
    } else {
      ++closed;
    }
    const Session s = ReadSession(session);
    long kept = 0;
    for (const Experiment& e : s.experiments) {
      for (double v : e.channel("force").samples) {
        ASSERT_EQ(v, static_cast<double>(kept)) << "run " << run << ": samples missing or out of order in " << e.label;
        ++kept;
      }
    }
    EXPECT_GE(kept, owed) << "run " << run << ": lost samples handed over more than " << bound_s << " s before the kill";
    EXPECT_LE(kept, handed + 50) << "run " << run << ": more samples than were handed over";
    for (const auto& [n, at] : log) {  // how long before the kill the first lost sample was handed over
      if (n > kept) {
        worst_loss_s = std::max(worst_loss_s, (kill_ns - at) * 1e-9);
        break;
      }
    }
    files += " " + session;
  }
  std::cout << fmt::format("kill -9: {} runs, {} recovered, {} closed before the kill, {} killed before the "
                           "journal had its header; oldest lost sample handed over {:.0f} ms before the kill\n",
                           runs, recovered, closed, empty, worst_loss_s * 1e3);
  EXPECT_GE(recovered, runs / 2);
  const std::string python = PythonWithH5py();
  if (python.empty()) GTEST_SKIP() << "python3 with h5py and numpy not found";
  const char* script = R"(
import sys, h5py
for path in sys.argv[1:]:
    with h5py.File(path, "r") as h:
        assert h.attrs["format"] == "damper-session", path
        for g in h["experiments"].values():
            assert g["time"].shape == g["force"].shape, path
            g["force"][:]
print(len(sys.argv) - 1, "files open in h5py")
)";
  EXPECT_EQ(RunPython(python, dir, script, files), 0);
}

}  // namespace
}  // namespace strut::daq
