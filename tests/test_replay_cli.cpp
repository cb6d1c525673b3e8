// `strut replay` as a process (docs/replay.md): sessions of `strut sim matrix` and of another tool
// (h5py) replayed and re-recorded bit for bit, the original and the re-recording identified to the
// same digits, the stream sent to a UDP receiver, the runner's stored cycles, and bad input.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "python_peer.h"
#include "replay_fixtures.h"
#include "strut/daq/replay.h"
#include "strut/rig/steady_state.h"
#include "strut_cli.h"

namespace strut::daq {
namespace {

using test::ExpectSameDatasetsInH5py;
using test::ExpectSameSamples;
using test::Receiver;
using test::RecordedSession;
using test::RunStrut;
using test::SameBits;
using test::TempDir;
namespace fs = std::filesystem;

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
