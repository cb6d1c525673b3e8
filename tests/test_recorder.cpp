// The streaming recorder (daq/recorder.h, docs/recording.md): what it records reads back sample
// for sample and passes the contract check; bad calls get errors naming the experiment and
// channel; a full disk or a slow one ends in a clear failure with the data kept; a power cut
// (simulated by keeping only what was synced) loses at most what the durability bound allows, and
// a torn journal reads up to its last intact record. h5py's reading, `strut recover` and kill -9 of
// a recording process: test_recorder_cli.cpp.
#include <gtest/gtest.h>

#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <thread>

#include "recorder_fixtures.h"
#include "session_events.h"
#include "strut/daq/recorder.h"
#include "strut/daq/session.h"
#include "test_support.h"

namespace strut::daq {
namespace {

using strut::test::Block;
using strut::test::Metadata;
using strut::test::NowNs;
using strut::test::Periodic;
using strut::test::RecordCutOff;
using strut::test::TempDir;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

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

// The message of the RecorderError a call throws ("" when none).
constexpr auto ErrorOf = [](auto&& call) { return strut::test::ErrorOf<RecorderError>(call); };

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

}  // namespace
}  // namespace strut::daq
