// Session files: round trips, files from other writers (h5py, MATLAB-style), one test per defect
// the reader must name, and the writer's crash safety (`strut info`: test_info_cli.cpp).
#include <gtest/gtest.h>
#include <hdf5.h>
#include <spdlog/sinks/ringbuffer_sink.h>
#include <spdlog/spdlog.h>
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <initializer_list>
#include <limits>
#include <nlohmann/json.hpp>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "python_peer.h"
#include "session_checks.h"
#include "session_file_fixtures.h"
#include "strut/daq/session.h"
#include "test_support.h"

namespace {

using strut::daq::Channel;
using strut::daq::Experiment;
using strut::daq::ExperimentKind;
using strut::daq::ReadSession;
using strut::daq::Session;
using strut::daq::SessionError;
using strut::daq::WriteOptions;
using strut::daq::WriteSession;
using strut::test::ExpectMentions;
using strut::test::ExpectSameSession;
using strut::test::FileEditor;
using strut::test::FileSizeLimit;
using strut::test::MakeDrop;
using strut::test::MakePeriodic;
using strut::test::MakeSession;
using strut::test::MakeStatic;
using strut::test::PythonWithH5py;
using strut::test::RunPython;
using strut::test::TempDir;
using strut::test::TimeAxis;
using strut::test::WriteGoodFile;

constexpr double kTwoPi = 2 * std::numbers::pi;

// ---------------------------------------------------------------------------------------------
// Files

// The message of the SessionError ReadSession throws (a test failure when it does not throw).
std::string ReadError(const std::string& path) {
  try {
    ReadSession(path);
  } catch (const SessionError& e) {
    return e.what();
  }
  ADD_FAILURE() << "ReadSession(" << path << ") accepted a defective file";
  return {};
}

std::size_t LineCount(const std::string& text) {
  return text.empty() ? 0
                      : static_cast<std::size_t>(std::count(text.begin(), text.end(), '\n')) + 1;
}

// A good session file broken by `edit` in a temporary directory, and the error the reader names.
struct BrokenFile {
  explicit BrokenFile(const std::function<void(FileEditor&)>& edit) : path(WriteGoodFile(dir)) {
    {
      FileEditor editor(path);
      edit(editor);
    }
    error = ReadError(path);
  }
  TempDir dir;
  std::string path;
  std::string error;
};

// Replaces the default logger while alive and keeps what was logged.
class CapturedLog {
 public:
  CapturedLog()
      : previous_(spdlog::default_logger()),
        sink_(std::make_shared<spdlog::sinks::ringbuffer_sink_mt>(64)) {
    auto logger = std::make_shared<spdlog::logger>("captured", sink_);
    logger->set_level(spdlog::level::warn);
    spdlog::set_default_logger(logger);
  }
  ~CapturedLog() { spdlog::set_default_logger(previous_); }
  std::string Text() const {
    std::string text;
    for (const std::string& line : sink_->last_formatted()) text += line;
    return text;
  }

 private:
  std::shared_ptr<spdlog::logger> previous_;
  std::shared_ptr<spdlog::sinks::ringbuffer_sink_mt> sink_;
};

// ---------------------------------------------------------------------------------------------
// Round trips

TEST(SessionFiles, RoundTripKeepsAllFieldsAndSamples) {
  TempDir dir;
  const Session written = MakeSession();
  WriteSession(dir.file("s.h5"), written);
  const Session read = ReadSession(dir.file("s.h5"));
  EXPECT_EQ(read.source_path, dir.file("s.h5"));
  ExpectSameSession(written, read);
  EXPECT_FALSE(std::filesystem::exists(dir.file("s.h5.partial")));
}

std::vector<hsize_t> ChunkOf(const std::string& path, const std::string& dataset_path,
                             int* filters) {
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  const hid_t dataset = H5Dopen2(file, dataset_path.c_str(), H5P_DEFAULT);
  const hid_t create = H5Dget_create_plist(dataset);
  std::vector<hsize_t> chunk;
  if (H5Pget_layout(create) == H5D_CHUNKED) {
    chunk.resize(1);
    H5Pget_chunk(create, 1, chunk.data());
  }
  *filters = H5Pget_nfilters(create);
  H5Pclose(create);
  H5Dclose(dataset);
  H5Fclose(file);
  return chunk;
}

TEST(SessionFiles, RoundTripWithoutCompressionWritesContiguousDatasets) {
  TempDir dir;
  const Session written = MakeSession();
  WriteSession(dir.file("s.h5"), written, WriteOptions{.gzip_level = 0, .chunk_samples = 0});
  ExpectSameSession(written, ReadSession(dir.file("s.h5")));
  int filters = -1;
  EXPECT_TRUE(ChunkOf(dir.file("s.h5"), "/experiments/a/force", &filters).empty());
  EXPECT_EQ(filters, 0);
}

TEST(SessionFiles, RoundTripWithGzipUsesRequestedOrAutomaticChunks) {
  TempDir dir;
  const Session written = MakeSession();
  WriteSession(dir.file("auto.h5"), written, WriteOptions{.gzip_level = 9, .chunk_samples = 0});
  WriteSession(dir.file("small.h5"), written, WriteOptions{.gzip_level = 1, .chunk_samples = 64});
  WriteSession(dir.file("plain.h5"), written, WriteOptions{.gzip_level = 0, .chunk_samples = 100});
  for (const char* name : {"auto.h5", "small.h5", "plain.h5"}) {
    SCOPED_TRACE(name);
    ExpectSameSession(written, ReadSession(dir.file(name)));
  }
  int filters = 0;
  EXPECT_EQ(ChunkOf(dir.file("auto.h5"), "/experiments/a/force", &filters),
            std::vector<hsize_t>{300});  // whole dataset: shorter than the automatic chunk
  EXPECT_EQ(filters, 2);                 // shuffle + deflate
  EXPECT_EQ(ChunkOf(dir.file("small.h5"), "/experiments/a/force", &filters),
            std::vector<hsize_t>{64});
  EXPECT_EQ(filters, 2);
  EXPECT_EQ(ChunkOf(dir.file("plain.h5"), "/experiments/a/force", &filters),
            std::vector<hsize_t>{100});
  EXPECT_EQ(filters, 0);
}

TEST(SessionFiles, KeepsExperimentsInRecordingOrder) {
  TempDir dir;
  Session s = MakeSession();
  s.experiments = {MakePeriodic("z1"), MakeStatic("a2"), MakeDrop("m3")};
  WriteSession(dir.file("s.h5"), s);
  const Session read = ReadSession(dir.file("s.h5"));
  ASSERT_EQ(read.experiments.size(), 3u);
  EXPECT_EQ(read.experiments[0].label, "z1");
  EXPECT_EQ(read.experiments[1].label, "a2");
  EXPECT_EQ(read.experiments[2].label, "m3");
}

TEST(SessionFiles, ExperimentSessionTimesComeFromStartTimesElseFromTheOrder) {
  EXPECT_EQ(strut::daq::ParseUtcIso8601("1970-01-02T00:00:01Z"), 86401.0);
  EXPECT_NEAR(*strut::daq::ParseUtcIso8601("2026-12-03T15:36:54.25Z") - *strut::daq::ParseUtcIso8601("2026-12-03T15:36:54Z"), 0.25, 1e-6);
  for (const char* bad : {"", "2026-12-03", "2026-12-03T15:36:54", "2026-13-03T15:36:54Z", "2026-12-03T15:36:54Zx"})
    EXPECT_FALSE(strut::daq::ParseUtcIso8601(bad).has_value()) << bad;

  Session s = MakeSession();
  s.experiments = {MakePeriodic("z1"), MakePeriodic("a2"), MakePeriodic("m3"), MakePeriodic("b4")};
  // No start times: by the order in the file.
  EXPECT_EQ(strut::daq::ExperimentSessionTimes(s), (std::vector<double>{0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0}));
  // Start times on every experiment: by them (a pause before the last experiment shows).
  const char* starts[] = {"2026-12-03T10:00:00Z", "2026-12-03T10:05:00Z", "2026-12-03T10:10:00Z", "2026-12-03T10:50:00Z"};
  for (std::size_t i = 0; i < 4; ++i) s.experiments[i].extra_attributes["started_utc"] = starts[i];
  EXPECT_EQ(strut::daq::ExperimentSessionTimes(s), (std::vector<double>{0.0, 0.1, 0.2, 1.0}));
  // Kept through a file.
  TempDir dir;
  WriteSession(dir.file("s.h5"), s);
  EXPECT_EQ(strut::daq::ExperimentSessionTimes(ReadSession(dir.file("s.h5"))), (std::vector<double>{0.0, 0.1, 0.2, 1.0}));
  // One unreadable or missing start time: the order again.
  s.experiments[2].extra_attributes["started_utc"] = "yesterday";
  EXPECT_EQ(strut::daq::ExperimentSessionTimes(s), (std::vector<double>{0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0}));
  s.experiments.resize(1);
  EXPECT_EQ(strut::daq::ExperimentSessionTimes(s), (std::vector<double>{0.0}));
}

TEST(SessionFiles, TransducerZerosAreOptionalMetadataReadBackWithTheirSd) {
  Session s = MakeSession();
  EXPECT_TRUE(strut::daq::ReadRecordedZeros(s).empty());  // other tools' sessions stay valid without
  strut::daq::RecordZeros({.load_cell = strut::daq::MeasuredZero{58.5, 3.0},
                           .stroke = strut::daq::MeasuredZero{-1.25e-3, 4.0e-5}},
                          s);
  TempDir dir;
  WriteSession(dir.file("s.h5"), s);
  const Session back = ReadSession(dir.file("s.h5"));
  const auto zeros = strut::daq::ReadRecordedZeros(back);
  ASSERT_TRUE(zeros.load_cell && zeros.stroke);
  EXPECT_EQ(zeros.load_cell->value, 58.5);
  EXPECT_EQ(zeros.load_cell->sd, 3.0);
  EXPECT_EQ(zeros.stroke->value, -1.25e-3);
  EXPECT_EQ(zeros.stroke->sd, 4.0e-5);
  // One of the two alone.
  strut::daq::RecordZeros({.stroke = strut::daq::MeasuredZero{2e-3, 1e-4}}, s);
  EXPECT_FALSE(strut::daq::ReadRecordedZeros(s).load_cell);
  EXPECT_EQ(strut::daq::ReadRecordedZeros(s).stroke->value, 2e-3);
  // A zero without its sd, or with one that is not positive, names the file and the attribute.
  const auto error = [&](const char* attribute, strut::daq::AttributeValue value) {
    Session bad = back;
    for (auto& g : bad.metadata)
      if (g.name == "calibration") g.attributes[attribute] = value;
    bad.source_path = "bad.h5";
    try {
      strut::daq::ReadRecordedZeros(bad);
    } catch (const SessionError& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  EXPECT_EQ(error("stroke_zero_sd", 0.0), "bad.h5: group '/calibration', attribute 'stroke_zero_sd': not a positive number");
  EXPECT_EQ(error("load_cell_zero", std::string("sixty")),
            "bad.h5: group '/calibration', attribute 'load_cell_zero': not a finite number");
  Session no_sd = back;
  for (auto& g : no_sd.metadata)
    if (g.name == "calibration") g.attributes.erase("load_cell_zero_sd");
  EXPECT_THROW(strut::daq::ReadRecordedZeros(no_sd), SessionError);
}

TEST(SessionFiles, WriteReplacesAnExistingFileAndLeavesNoPartialFile) {
  TempDir dir;
  const std::string path = dir.file("s.h5");
  std::ofstream(path) << "old contents";
  WriteSession(path, MakeSession());
  EXPECT_EQ(ReadSession(path).damper_serial, "MLG-0042");
  EXPECT_FALSE(std::filesystem::exists(path + ".partial"));
}

TEST(SessionFiles, WriteRefusesAnInvalidSessionAndCreatesNoFile) {
  TempDir dir;
  Session s = MakeSession();
  s.experiments[0].frequency = 0;
  const std::string path = dir.file("s.h5");
  try {
    WriteSession(path, s);
    FAIL() << "an invalid session was written";
  } catch (const SessionError& e) {
    ExpectMentions(e.what(), {path, "not written", "experiment 'a'", "attribute 'frequency'"});
  }
  EXPECT_FALSE(std::filesystem::exists(path));
  EXPECT_FALSE(std::filesystem::exists(path + ".partial"));
}

TEST(SessionFiles, WriteFailureNamesThePathAndRemovesThePartialFile) {
  TempDir dir;
  const std::string path = dir.file("no-such-directory/s.h5");
  try {
    WriteSession(path, MakeSession());
    FAIL() << "writing into a missing directory succeeded";
  } catch (const SessionError& e) {
    ExpectMentions(e.what(), {path, "cannot write"});
  }
  EXPECT_TRUE(std::filesystem::is_empty(dir.path()));
}

TEST(SessionFiles, WriteFailingHalfWayNamesThePathAndRemovesThePartialFile) {
  TempDir dir;
  const std::string path = dir.file("s.h5");
  std::string message;
  {
    const FileSizeLimit limit(16 * 1024);  // the session needs about 50 KiB
    try {
      WriteSession(path, MakeSession(), WriteOptions{.gzip_level = 0});
    } catch (const SessionError& e) {
      message = e.what();
    }
  }
  ExpectMentions(message, {path, "cannot write"});
  EXPECT_TRUE(std::filesystem::is_empty(dir.path()));
}

TEST(SessionFiles, WriteRejectsAGzipLevelOutsideZeroToNine) {
  TempDir dir;
  EXPECT_THROW(WriteSession(dir.file("s.h5"), MakeSession(), WriteOptions{.gzip_level = 12}),
               SessionError);
  EXPECT_TRUE(std::filesystem::is_empty(dir.path()));
}

// ---------------------------------------------------------------------------------------------
// Files from other writers

TEST(SessionFiles, ReadsAFileWrittenByH5py) {
  const std::string python = PythonWithH5py();
  if (python.empty()) GTEST_SKIP() << "python3 with h5py and numpy not found";
  TempDir dir;
  const std::string path = dir.file("h5py.h5");
  const char* script = R"(
import sys, h5py, numpy as np
sr, f, periods = 400.0, 4.0, 4
n = int(periods * sr / f)
t = np.arange(n) / sr
w = 2 * np.pi * f * t
with h5py.File(sys.argv[1], "w") as h:
    h.attrs["format"] = "damper-session"            # str: variable-length UTF-8
    h.attrs["format_version"] = np.int64(1)
    h.attrs["created_utc"] = "2024-05-01T12:00:00Z"
    h.attrs["damper_serial"] = "SN-\u00fc42"
    h.attrs["rig"] = "h5py-rig"
    g = h.create_group("experiments/920713b")
    g.attrs["kind"] = "periodic"
    g.attrs["status"] = "complete"
    g.attrs["sample_rate"] = np.float32(sr)
    g.attrs["frequency"] = f
    g.attrs["amplitude"] = 0.02
    g.attrs["static_position"] = 0.1
    g.attrs["waveform"] = "sine"
    g.attrs["periods"] = np.int16(periods)
    g.attrs["group"] = "low"
    g.attrs["operator"] = "x"
    g.attrs["calibrated"] = True
    g.attrs["gains"] = np.array([1.5, 2.0])
    g.create_dataset("time", data=t).attrs["units"] = "s"
    g.create_dataset("stroke", data=0.1 + 0.02 * np.sin(w), compression="gzip", chunks=(64,)).attrs["units"] = "m"
    g.create_dataset("force", data=(1000 * np.cos(w)).reshape(-1, 1)).attrs["units"] = "N"
    p = g.create_dataset("pressure", data=(2e5 + 1e4 * np.sin(w)).astype(np.float32))
    p.attrs["units"] = "Pa"
    p.attrs["reference"] = "gauge"
    g.create_dataset("temperature", data=np.full(n, 293.15)).attrs["units"] = "K"
    g.create_dataset("notes", data=np.arange(3.0))
)";
  ASSERT_EQ(RunPython(python, dir, script, path), 0);

  const Session s = ReadSession(path);
  EXPECT_EQ(s.format_version, 1);
  EXPECT_EQ(s.damper_serial, "SN-\u00fc42");
  EXPECT_EQ(s.rig, "h5py-rig");
  ASSERT_EQ(s.experiments.size(), 1u);
  const Experiment& e = s.experiment("920713b");
  EXPECT_EQ(e.kind, ExperimentKind::kPeriodic);
  EXPECT_EQ(e.sample_rate, 400.0);
  EXPECT_EQ(e.periods, 4);
  EXPECT_EQ(e.group, "low");
  EXPECT_EQ(e.sample_count(), 400u);
  EXPECT_EQ(e.extra_attributes.at("operator"), "x");
  EXPECT_EQ(e.extra_attributes.at("calibrated"), "TRUE");
  EXPECT_EQ(e.extra_attributes.at("gains"), "[1.5, 2]");
  ASSERT_EQ(e.channels.size(), 4u);  // `notes` has no units and another length: not a channel
  EXPECT_EQ(e.channels[0].name, "stroke");
  EXPECT_EQ(e.channels[1].name, "force");
  EXPECT_EQ(e.channels[2].name, "pressure");
  EXPECT_EQ(e.channels[3].name, "temperature");
  EXPECT_EQ(e.channel("temperature").units, "K");
  const Channel& force = e.channel("force");
  ASSERT_EQ(force.samples.size(), 400u);
  EXPECT_NEAR(force.samples[10], 1000 * std::cos(kTwoPi * 4.0 * 10 / 400.0), 1e-9);
  const Channel& pressure = e.channel("pressure");
  EXPECT_EQ(pressure.reference, "gauge");
  EXPECT_NEAR(pressure.samples[5], 2e5 + 1e4 * std::sin(kTwoPi * 4.0 * 5 / 400.0), 0.05);
  EXPECT_NEAR(e.absolute_pressure()[5], pressure.samples[5] + 101325.0, 1e-9);
}

TEST(SessionFiles, ReadsAMatlabStyleFile) {
  // MATLAB's h5create/h5writeatt: space-padded fixed strings, doubles for every number,
  // attributes of shape [1], vectors of shape (1,N) in float32.
  TempDir dir;
  const std::string path = WriteGoodFile(dir);
  {
    FileEditor edit(path);
    edit.SetString("/", "format", "damper-session", false, H5T_STR_SPACEPAD);
    edit.SetString("/", "rig", "matlab rig   ", false, H5T_STR_SPACEPAD);
    edit.SetNumber("/", "format_version", 1.0, H5T_IEEE_F64LE, {1});
    edit.SetNumber("/experiments/a", "periods", 3.0, H5T_IEEE_F64LE, {1, 1});
    edit.SetNumber("/experiments/a", "sample_rate", 200, H5T_STD_U16LE);
    const Experiment a = MakePeriodic("a");
    edit.SetDataset("/experiments/a/stroke", a.channel("stroke").samples, {1, 300}, "m", nullptr,
                    H5T_IEEE_F32LE);
  }
  const Session s = ReadSession(path);
  EXPECT_EQ(s.rig, "matlab rig");
  const Experiment& a = s.experiment("a");
  EXPECT_EQ(a.periods, 3);
  EXPECT_EQ(a.sample_rate, 200.0);
  const Experiment original = MakePeriodic("a");
  const std::vector<double>& expected = original.channel("stroke").samples;
  ASSERT_EQ(a.channel("stroke").samples.size(), expected.size());
  for (std::size_t i = 0; i < expected.size(); ++i) {
    EXPECT_NEAR(a.channel("stroke").samples[i], expected[i], 1e-7);
  }
}

TEST(SessionFiles, H5pyReadsWhatStrutWrote) {
  const std::string python = PythonWithH5py();
  if (python.empty()) GTEST_SKIP() << "python3 with h5py and numpy not found";
  TempDir dir;
  const std::string path = WriteGoodFile(dir);
  const char* script = R"(
import sys, h5py, numpy as np
def text(v):
    return v.decode() if isinstance(v, bytes) else str(v)
with h5py.File(sys.argv[1], "r") as h:
    assert text(h.attrs["format"]) == "damper-session"
    # variable-length UTF-8: str in h5py, not bytes
    assert h.attrs["format"] == "damper-session" and isinstance(h.attrs["rig"], str)
    assert h["experiments/a/stroke"].attrs["units"] == "m"
    assert h["experiments/a"].attrs["kind"] == "periodic"
    assert h.attrs["format_version"] == 1 and h.attrs["format_version"].dtype.kind == "i"
    assert text(h.attrs["created_utc"]) == "2026-11-22T05:32:50Z"
    assert text(h.attrs["damper_serial"]) == "MLG-0042"
    assert text(h.attrs["rig"]) == "shaker-2"
    assert sorted(h["experiments"].keys()) == ["a", "b", "c"]
    a = h["experiments/a"]
    assert text(a.attrs["kind"]) == "periodic" and text(a.attrs["status"]) == "complete"
    assert a.attrs["sample_rate"] == 200.0 and a.attrs["frequency"] == 2.0
    assert a.attrs["amplitude"] == 0.01 and a.attrs["static_position"] == 0.1
    assert a.attrs["periods"] == 3 and a.attrs["periods"].dtype.kind == "i"
    assert text(a.attrs["waveform"]) == "sine" and text(a.attrs["group"]) == "high"
    assert text(a.attrs["operator"]) == "jd"
    t = a["time"][:]
    assert a["time"].dtype == np.float64 and t.shape == (300,) and t[0] == 0.0
    assert np.allclose(t, np.arange(300) / 200.0, rtol=0, atol=1e-12)
    w = 2 * np.pi * 2.0 * t
    assert a["stroke"].compression == "gzip"
    assert text(a["stroke"].attrs["units"]) == "m"
    assert np.allclose(a["stroke"][:], 0.1 + 0.01 * np.sin(w), rtol=0, atol=1e-12)
    assert np.allclose(a["force"][:], 5000 + 2000 * np.sin(w), rtol=0, atol=1e-9)
    assert text(a["pressure"].attrs["reference"]) == "absolute"
    assert text(a["temperature"].attrs["units"]) == "K"
    b = h["experiments/b"]
    assert text(b.attrs["kind"]) == "drop" and b.attrs["drop_mass"] == 500.0
    assert text(b["pressure"].attrs["reference"]) == "gauge"
    assert "frequency" not in b.attrs
print("h5py peer check passed")
)";
  EXPECT_EQ(RunPython(python, dir, script, path), 0);
}

TEST(SessionFiles, AcceptsAnAbortedPeriodicExperimentWithoutWholePeriods) {
  TempDir dir;
  Session s = MakeSession();
  Experiment& a = s.experiments[0];
  a.status = "aborted";
  a.periods = 0;
  a.time.resize(123);
  for (Channel& c : a.channels) c.samples.resize(123);
  WriteSession(dir.file("s.h5"), s);
  EXPECT_EQ(ReadSession(dir.file("s.h5")).experiment("a").sample_count(), 123u);
}

TEST(SessionFiles, AcceptsASampleCountOneOffThePeriods) {
  TempDir dir;
  const std::string path = WriteGoodFile(dir);
  FileEditor(path).Resize("/experiments/a", 301, 200, "absolute");
  EXPECT_EQ(ReadSession(path).experiment("a").sample_count(), 301u);
}

TEST(SessionFiles, WarnsButAcceptsATimeAxisSlightlyOffTheSampleRate) {
  TempDir dir;
  const std::string path = WriteGoodFile(dir);
  std::vector<double> t = TimeAxis(300, 200);
  for (double& ti : t) ti *= 1.005;  // a DAQ clock 0.5 % slow
  FileEditor(path).Overwrite("/experiments/a/time", t);
  CapturedLog log;
  EXPECT_NO_THROW(ReadSession(path));
  ExpectMentions(log.Text(), {path, "experiment 'a'", "dataset 'time'", "+0.500%"});
}

// ---------------------------------------------------------------------------------------------
// Files that are not session files at all

TEST(SessionFiles, RejectsAMissingFile) {
  TempDir dir;
  ExpectMentions(ReadError(dir.file("absent.h5")), {dir.file("absent.h5"), "no such file"});
}

TEST(SessionFiles, RejectsAnEmptyFile) {
  TempDir dir;
  std::ofstream(dir.file("empty.h5")).close();
  ExpectMentions(ReadError(dir.file("empty.h5")), {dir.file("empty.h5"), "empty file"});
}

TEST(SessionFiles, RejectsAFileThatIsNotHdf5) {
  TempDir dir;
  std::ofstream(dir.file("notes.h5")) << "time,stroke,force\n0,0.1,5000\n";
  ExpectMentions(ReadError(dir.file("notes.h5")), {dir.file("notes.h5"), "not an HDF5 file"});
}

TEST(SessionFiles, RejectsATruncatedFile) {
  TempDir dir;
  const std::string path = WriteGoodFile(dir);
  std::filesystem::resize_file(path, std::filesystem::file_size(path) / 2);
  ExpectMentions(ReadError(path), {path, "truncated"});
}

// ---------------------------------------------------------------------------------------------
// One test per defect: the message names the file, the experiment and the item

TEST(SessionFiles, RejectsAWrongFormatName) {
  const BrokenFile f([](FileEditor& edit) { edit.SetString("/", "format", "other-format"); });
  ExpectMentions(f.error, {f.path, "attribute 'format'", "other-format", "damper-session"});
}

TEST(SessionFiles, RejectsAnUnsupportedFormatVersion) {
  const BrokenFile f([](FileEditor& edit) { edit.SetNumber("/", "format_version", 2, H5T_STD_I32LE); });
  ExpectMentions(f.error, {f.path, "attribute 'format_version'", "unsupported version 2"});
}

TEST(SessionFiles, RejectsAMissingRootAttribute) {
  const BrokenFile f([](FileEditor& edit) { edit.RemoveAttribute("/", "damper_serial"); });
  EXPECT_EQ(f.error, f.path + ": attribute 'damper_serial': missing");
}

TEST(SessionFiles, RejectsAFileWithoutExperimentsGroup) {
  const BrokenFile f([](FileEditor& edit) { edit.Remove("/experiments"); });
  EXPECT_EQ(f.error, f.path + ": group '/experiments': missing");
}

TEST(SessionFiles, RejectsAMissingExperimentAttribute) {
  const BrokenFile f([](FileEditor& edit) { edit.RemoveAttribute("/experiments/b", "sample_rate"); });
  EXPECT_EQ(f.error, f.path + ": experiment 'b': attribute 'sample_rate': missing");
}

TEST(SessionFiles, RejectsAStringWhereANumberIsRequired) {
  const BrokenFile f([](FileEditor& edit) { edit.SetString("/experiments/a", "frequency", "2.0", true); });
  EXPECT_EQ(f.error, f.path +
                       ": experiment 'a': attribute 'frequency': expected a number, "
                       "found a string (\"2.0\")");
}

TEST(SessionFiles, RejectsANumberWhereAStringIsRequired) {
  const BrokenFile f([](FileEditor& edit) { edit.SetNumber("/experiments/c", "kind", 1, H5T_STD_I8LE); });
  EXPECT_EQ(f.error,
            f.path + ": experiment 'c': attribute 'kind': expected a string, found an integer");
}

TEST(SessionFiles, RejectsAnUnknownKind) {
  const BrokenFile f([](FileEditor& edit) { edit.SetString("/experiments/c", "kind", "ramp"); });
  EXPECT_EQ(f.error, f.path +
                       ": experiment 'c': attribute 'kind': 'ramp' is not "
                       "\"periodic\", \"drop\" or \"static\"");
}

TEST(SessionFiles, RejectsAnUnknownStatus) {
  const BrokenFile f([](FileEditor& edit) { edit.SetString("/experiments/b", "status", "running"); });
  ExpectMentions(f.error, {f.path, "experiment 'b'", "attribute 'status'", "'running'"});
}

TEST(SessionFiles, RejectsANonPositiveSampleRate) {
  const BrokenFile f([](FileEditor& edit) { edit.SetNumber("/experiments/c", "sample_rate", -10); });
  EXPECT_EQ(f.error,
            f.path + ": experiment 'c': attribute 'sample_rate': must be > 0, found -10");
}

TEST(SessionFiles, RejectsANonPositiveFrequency) {
  const BrokenFile f([](FileEditor& edit) { edit.SetNumber("/experiments/a", "frequency", 0); });
  EXPECT_EQ(f.error,
            f.path + ": experiment 'a': attribute 'frequency': must be > 0, found 0");
}

TEST(SessionFiles, RejectsANonPositiveAmplitude) {
  const BrokenFile f([](FileEditor& edit) { edit.SetNumber("/experiments/a", "amplitude", -0.01); });
  ExpectMentions(f.error, {f.path, "experiment 'a'", "attribute 'amplitude'", "must be > 0"});
}

TEST(SessionFiles, RejectsAMissingStaticPosition) {
  const BrokenFile f([](FileEditor& edit) { edit.RemoveAttribute("/experiments/a", "static_position"); });
  EXPECT_EQ(f.error, f.path + ": experiment 'a': attribute 'static_position': missing");
}

TEST(SessionFiles, RejectsANegativeStaticPosition) {
  const BrokenFile f([](FileEditor& edit) { edit.SetNumber("/experiments/a", "static_position", -0.1); });
  ExpectMentions(f.error, {f.path, "experiment 'a'", "attribute 'static_position'", ">= 0"});
}

TEST(SessionFiles, RejectsAMissingWaveform) {
  const BrokenFile f([](FileEditor& edit) { edit.RemoveAttribute("/experiments/a", "waveform"); });
  EXPECT_EQ(f.error, f.path + ": experiment 'a': attribute 'waveform': missing");
}

TEST(SessionFiles, RejectsFractionalPeriods) {
  const BrokenFile f([](FileEditor& edit) { edit.SetNumber("/experiments/a", "periods", 2.5); });
  EXPECT_EQ(f.error,
            f.path + ": experiment 'a': attribute 'periods': must be a whole number, found 2.5");
}

TEST(SessionFiles, RejectsZeroPeriodsInACompleteExperiment) {
  const BrokenFile f([](FileEditor& edit) { edit.SetNumber("/experiments/a", "periods", 0, H5T_STD_I64LE); });
  EXPECT_EQ(f.error, f.path + ": experiment 'a': attribute 'periods': must be >= 1, found 0");
}

TEST(SessionFiles, RejectsASampleCountThatDoesNotMatchThePeriods) {
  const BrokenFile f([](FileEditor& edit) { edit.Resize("/experiments/a", 310, 200, "absolute"); });
  EXPECT_EQ(f.error, f.path +
                       ": experiment 'a': samples: 310 samples, but periods * "
                       "sample_rate / frequency = 3 * 200 / 2 = 300 (±1 accepted)");
}

TEST(SessionFiles, RejectsAMissingDropMass) {
  const BrokenFile f([](FileEditor& edit) { edit.RemoveAttribute("/experiments/b", "drop_mass"); });
  EXPECT_EQ(f.error, f.path + ": experiment 'b': attribute 'drop_mass': missing");
}

TEST(SessionFiles, RejectsANonPositiveImpactVelocity) {
  const BrokenFile f([](FileEditor& edit) { edit.SetNumber("/experiments/b", "impact_velocity", 0); });
  EXPECT_EQ(f.error,
            f.path + ": experiment 'b': attribute 'impact_velocity': must be > 0, found 0");
}

TEST(SessionFiles, RejectsAMissingChannelDataset) {
  const BrokenFile f([](FileEditor& edit) { edit.Remove("/experiments/b/pressure"); });
  EXPECT_EQ(f.error, f.path + ": experiment 'b': channel 'pressure': missing dataset");
}

TEST(SessionFiles, RejectsAMissingTimeDataset) {
  const BrokenFile f([](FileEditor& edit) { edit.Remove("/experiments/c/time"); });
  EXPECT_EQ(f.error, f.path + ": experiment 'c': dataset 'time': missing dataset");
}

TEST(SessionFiles, RejectsAChannelWithoutUnits) {
  const BrokenFile f([](FileEditor& edit) { edit.RemoveAttribute("/experiments/a/force", "units"); });
  EXPECT_EQ(f.error,
            f.path + ": experiment 'a': channel 'force': attribute 'units': missing");
}

TEST(SessionFiles, RejectsUnknownUnits) {
  const BrokenFile f([](FileEditor& edit) { edit.SetString("/experiments/a/stroke", "units", "mm"); });
  ExpectMentions(f.error, {f.path, "experiment 'a'", "channel 'stroke': attribute 'units'",
                                   "unknown units 'mm'"});
}

TEST(SessionFiles, RejectsUnknownUnitsOnAFurtherChannel) {
  const BrokenFile f([](FileEditor& edit) { edit.SetString("/experiments/a/temperature", "units", "degC"); });
  ExpectMentions(
      f.error,
      {f.path, "experiment 'a'", "channel 'temperature': attribute 'units'", "unknown units 'degC'"});
}

TEST(SessionFiles, RejectsEmptyUnits) {
  const BrokenFile f([](FileEditor& edit) { edit.SetString("/experiments/b/force", "units", ""); });
  ExpectMentions(f.error,
                 {f.path, "experiment 'b'", "channel 'force': attribute 'units'", "empty"});
}

TEST(SessionFiles, RejectsUnitsOfTheWrongQuantity) {
  const BrokenFile f([](FileEditor& edit) { edit.SetString("/experiments/a/pressure", "units", "N"); });
  EXPECT_EQ(f.error,
            f.path + ": experiment 'a': channel 'pressure': attribute 'units': 'N', expected 'Pa'");
}

TEST(SessionFiles, RejectsTimeUnitsOtherThanSeconds) {
  const BrokenFile f([](FileEditor& edit) { edit.SetString("/experiments/a/time", "units", "ms"); });
  ExpectMentions(f.error,
                 {f.path, "experiment 'a'", "dataset 'time': attribute 'units'", "'ms'"});
}

TEST(SessionFiles, RejectsPressureWithoutReference) {
  const BrokenFile f([](FileEditor& edit) { edit.RemoveAttribute("/experiments/c/pressure", "reference"); });
  EXPECT_EQ(f.error,
            f.path + ": experiment 'c': channel 'pressure': attribute 'reference': missing");
}

TEST(SessionFiles, RejectsAnUnknownPressureReference) {
  const BrokenFile f([](FileEditor& edit) { edit.SetString("/experiments/c/pressure", "reference", "sealed"); });
  EXPECT_EQ(f.error, f.path +
                       ": experiment 'c': channel 'pressure': attribute 'reference': "
                       "'sealed' is neither \"absolute\" nor \"gauge\"");
}

TEST(SessionFiles, RejectsDatasetsOfDifferentLengths) {
  const BrokenFile f([](FileEditor& edit) {
    edit.SetDataset("/experiments/a/force", std::vector<double>(299, 1.0), {299}, "N");
  });
  EXPECT_EQ(f.error,
            f.path + ": experiment 'a': channel 'force': 299 samples, but 'time' has 300");
}

TEST(SessionFiles, RejectsNaNAndInfSamples) {
  TempDir dir;
  const std::string path = WriteGoodFile(dir);
  std::vector<double> force = MakePeriodic("a").channel("force").samples;
  force[120] = std::numeric_limits<double>::quiet_NaN();
  force[121] = std::numeric_limits<double>::infinity();
  force[200] = std::numeric_limits<double>::quiet_NaN();
  FileEditor(path).Overwrite("/experiments/a/force", force);
  EXPECT_EQ(ReadError(path),
            path + ": experiment 'a': channel 'force': 3 NaN/Inf samples (first at index 120)");
}

TEST(SessionFiles, RejectsTimeThatDoesNotStartAtZero) {
  TempDir dir;
  const std::string path = WriteGoodFile(dir);
  std::vector<double> t = TimeAxis(300, 200);
  for (double& ti : t) ti += 0.25;
  FileEditor(path).Overwrite("/experiments/a/time", t);
  EXPECT_EQ(ReadError(path), path +
                                 ": experiment 'a': dataset 'time': starts at 0.25 s, not at 0 "
                                 "(the first recorded sample)");
}

TEST(SessionFiles, RejectsTimeThatDoesNotIncrease) {
  TempDir dir;
  const std::string path = WriteGoodFile(dir);
  std::vector<double> t = TimeAxis(300, 200);
  std::swap(t[10], t[11]);
  FileEditor(path).Overwrite("/experiments/a/time", t);
  EXPECT_EQ(
      ReadError(path),
      path + ": experiment 'a': dataset 'time': not increasing at index 11 (0.05 s after 0.055 s)");
}

TEST(SessionFiles, RejectsTimeInconsistentWithTheSampleRate) {
  TempDir dir;
  const std::string path = WriteGoodFile(dir);
  std::vector<double> t = TimeAxis(300, 200);
  for (double& ti : t) ti *= 1.03;
  FileEditor(path).Overwrite("/experiments/a/time", t);
  ExpectMentions(ReadError(path),
                 {path, "experiment 'a'", "dataset 'time'", "+3.00% off 1/sample_rate"});
}

TEST(SessionFiles, RejectsTimeWithDroppedSamples) {
  TempDir dir;
  const std::string path = WriteGoodFile(dir);
  std::vector<double> t = TimeAxis(300, 200);
  for (std::size_t i = 150; i < t.size(); ++i) t[i] += 1.0 / 200;  // sample 150 was lost
  FileEditor(path).Overwrite("/experiments/a/time", t);
  EXPECT_EQ(ReadError(path), path +
                                 ": experiment 'a': dataset 'time': 1 step differs from "
                                 "1/sample_rate = 0.005 s by more than 50% (first at index 150: "
                                 "0.01 s): dropped or repeated samples");
}

TEST(SessionFiles, RejectsADatasetThatIsNotOneDimensional) {
  TempDir dir;
  const std::string path = WriteGoodFile(dir);
  FileEditor(path).SetDataset("/experiments/b/stroke", std::vector<double>(500, 0.1), {2, 250},
                              "m");
  EXPECT_EQ(ReadError(path),
            path + ": experiment 'b': channel 'stroke': not one-dimensional (shape 2 x 250)");
}

TEST(SessionFiles, RejectsAnEmptyExperiment) {
  const BrokenFile f([](FileEditor& edit) { edit.Resize("/experiments/c", 0, 10, "absolute"); });
  EXPECT_EQ(f.error, f.path + ": experiment 'c': samples: no samples (empty experiment)");
}

TEST(SessionFiles, ListsEveryDefectOnItsOwnLine) {
  const BrokenFile f([](FileEditor& edit) {
    edit.RemoveAttribute("/", "rig");
    edit.RemoveAttribute("/experiments/a", "frequency");
    edit.SetString("/experiments/b/force", "units", "kN");
  });
  const std::string message = f.error;
  EXPECT_EQ(message, f.path + ": attribute 'rig': missing\n" + f.path +
                         ": experiment 'a': attribute 'frequency': missing\n" + f.path +
                         ": experiment 'b': channel 'force': attribute 'units': unknown "
                         "units 'kN' (accepted: m, N, Pa, K, s, V, A, m/s, m/s^2, m/s2, kg, 1)");
  EXPECT_EQ(LineCount(message), 3u);
}

// ---------------------------------------------------------------------------------------------
// In memory

TEST(SessionFiles, ValidateAcceptsAGoodSession) {
  EXPECT_TRUE(strut::daq::Validate(MakeSession()).empty());
}

TEST(SessionFiles, ValidateNamesTheSameDefectsForAnInMemorySession) {
  Session s = MakeSession();
  s.experiments[0].frequency = 0;
  s.experiments[1].channels[1].samples.pop_back();
  s.experiments[2].channels[2].reference = "";
  const std::vector<std::string> defects = strut::daq::Validate(s);
  EXPECT_EQ(defects,
            (std::vector<std::string>{
                "<memory>: experiment 'a': attribute 'frequency': must be > 0, found 0",
                "<memory>: experiment 'b': channel 'force': 249 samples, but 'time' has 250",
                "<memory>: experiment 'c': channel 'pressure': attribute 'reference': "
                "missing (must be \"absolute\" or \"gauge\")"}));
  s.source_path = "rig.h5";
  EXPECT_EQ(strut::daq::Validate(s).front().rfind("rig.h5: experiment 'a'", 0), 0u);
}

TEST(SessionFiles, ValidateRejectsDuplicateLabelsAndChannels) {
  Session s = MakeSession();
  s.experiments.push_back(MakeStatic("c"));
  s.experiments[0].channels.push_back(s.experiments[0].channels[0]);
  const std::vector<std::string> defects = strut::daq::Validate(s);
  ASSERT_EQ(defects.size(), 2u);
  EXPECT_EQ(defects[0], "<memory>: experiment 'a': channel 'stroke': appears more than once");
  EXPECT_EQ(defects[1], "<memory>: experiment 'c': label: used by more than one experiment");
}

TEST(SessionFiles, AbsolutePressureAddsTheAmbientToGaugeReadings) {
  const Session s = MakeSession();
  const Experiment& drop = s.experiment("b");  // gauge
  EXPECT_DOUBLE_EQ(drop.absolute_pressure()[7], drop.channel("pressure").samples[7] + 101325.0);
  const Experiment& periodic = s.experiment("a");  // absolute
  EXPECT_EQ(periodic.absolute_pressure(), periodic.channel("pressure").samples);
}

TEST(SessionFiles, LookupsNameTheMissingExperimentOrChannel) {
  Session s = MakeSession();
  EXPECT_EQ(s.find_experiment("zz"), nullptr);
  EXPECT_EQ(s.experiment("a").find_channel("voltage"), nullptr);
  s.source_path = "rig.h5";
  try {
    s.experiment("zz");
    FAIL();
  } catch (const SessionError& e) {
    ExpectMentions(e.what(), {"rig.h5", "'zz'"});
  }
  try {
    s.experiment("a").channel("voltage");
    FAIL();
  } catch (const SessionError& e) {
    ExpectMentions(e.what(), {"experiment 'a'", "channel 'voltage'"});
  }
  EXPECT_EQ(strut::daq::ToString(ExperimentKind::kDrop), "drop");
  EXPECT_EQ(s.experiment("a").samples_per_period(), 100.0);
}

TEST(SessionFiles, UtcNowIsIso8601WithZuluSuffix) {
  const std::string now = strut::daq::UtcNowIso8601();
  ASSERT_EQ(now.size(), 20u);
  EXPECT_EQ(now[4], '-');
  EXPECT_EQ(now[10], 'T');
  EXPECT_EQ(now.back(), 'Z');
}

}  // namespace
