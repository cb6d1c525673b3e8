// The recorder's files through the CLI (docs/recording.md): `strut recover` turns a cut-off journal
// into a valid session and never removes its input unasked; h5py reads what the recorder and
// `strut sim` write with strings as str and numbers as numbers; kill -9 of a real recording child
// process (100 times) loses at most what the durability bound allows and `strut recover` mends
// every file.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>

#include <fmt/format.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <random>
#include <thread>

#include "python_peer.h"
#include "recorder_fixtures.h"
#include "strut/daq/recorder.h"
#include "strut/daq/session.h"
#include "strut_cli.h"

namespace strut::daq {
namespace {

using strut::test::Block;
using strut::test::Metadata;
using strut::test::NowNs;
using strut::test::Periodic;
using strut::test::PythonWithH5py;
using strut::test::RecordCutOff;
using strut::test::RunPython;
using strut::test::RunStrut;
using strut::test::TempDir;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

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
    const pid_t pid = test::Spawn({STRUT_RECORDER_CHILD, session, report, "2000", "10", "50",
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
