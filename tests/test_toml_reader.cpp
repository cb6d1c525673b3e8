// daq::TomlReader, the one TOML reading of the rig, simulated-rig and QC files: each error is the
// caller's type and names the file, the line and the key with what it holds instead.
#include <gtest/gtest.h>

#include <fstream>
#include <stdexcept>
#include <string>

#include "strut/daq/toml_reader.h"
#include "strut/qc/reference.h"
#include "strut/rig/safety.h"
#include "strut/rig/test_matrix.h"
#include "strut/sim/truth.h"
#include "test_support.h"

namespace {

class FileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};
using Reader = strut::daq::TomlReader<FileError>;

TEST(TomlReader, ReadsTypedValuesAndLeavesAbsentKeysEmpty) {
  const Reader r("f.toml");
  const toml::table root = r.Parse("rate = 2000\nname = \"rig 3\"\non = true\n[limits]\nupper = 0.25\ncount = 4\n");
  EXPECT_EQ(r.Number(root, "", "rate"), 2000.0);  // an integer is a number too
  EXPECT_EQ(r.Text(root, "", "name"), "rig 3");
  EXPECT_EQ(r.Bool(root, "", "on"), true);
  const toml::table& limits = r.Table(*root.get("limits"), "", "limits");
  EXPECT_EQ(r.Number(limits, Reader::In("limits"), "upper"), 0.25);
  EXPECT_EQ(r.Integer(limits, Reader::In("limits"), "count"), 4);
  EXPECT_FALSE(r.Number(limits, Reader::In("limits"), "lower").has_value());
  EXPECT_NO_THROW(r.RefuseUnknown(limits, Reader::In("limits"), {"upper", "count"}));
}

// The message a read throws as FileError ("" when none).
constexpr auto ErrorOf = [](auto&& call) { return strut::test::ErrorOf<FileError>(call); };

TEST(TomlReader, ErrorsNameTheFileLineKeyAndWhatWasFound) {
  const Reader r("f.toml");
  const std::string syntax = ErrorOf([&] { r.Parse("a = 1\nb = = 2\n"); });
  EXPECT_EQ(syntax.rfind("f.toml:2:", 0), 0u) << syntax;
  EXPECT_NE(syntax.find(": TOML syntax: "), std::string::npos) << syntax;
  const toml::table root = r.Parse("a = \"five\"\n[s]\nn = 2.5\nx = inf\nt = 3\nlist = [1]\nwhen = 1979-05-27\n");
  const toml::table& s = *root.get_as<toml::table>("s");
  const std::string in = Reader::In("s");
  EXPECT_EQ(ErrorOf([&] { r.Number(root, "", "a"); }), "f.toml:1: a: expected a number, got the string \"five\"");
  EXPECT_EQ(ErrorOf([&] { r.Integer(s, in, "n"); }), "f.toml:3: [s] n: expected an integer, got the number 2.5");
  EXPECT_EQ(ErrorOf([&] { r.Number(s, in, "x"); }), "f.toml:4: [s] x: expected a finite number, got the number inf");
  EXPECT_EQ(ErrorOf([&] { r.Bool(s, in, "t"); }), "f.toml:5: [s] t: expected true or false, got the integer 3");
  EXPECT_EQ(ErrorOf([&] { r.Text(s, in, "list"); }), "f.toml:6: [s] list: expected a string, got an array");
  EXPECT_EQ(ErrorOf([&] { r.Number(s, in, "when"); }), "f.toml:7: [s] when: expected a number, got a date or time");
  EXPECT_EQ(ErrorOf([&] { r.Table(*root.get("a"), "", "a"); }),
            "f.toml:1: a: expected a table ([a]), got the string \"five\"");
  EXPECT_EQ(ErrorOf([&] { r.Bool(root, "", "s"); }), "f.toml:2: s: expected true or false, got a table");
  EXPECT_EQ(ErrorOf([&] { r.RefuseUnknown(s, in, {"n", "x", "list", "when"}); }),
            "f.toml:5: [s] unknown key 't' (known: n, x, list, when)");
  EXPECT_EQ(ErrorOf([&] { r.Fail("no [limits] table"); }), "f.toml: no [limits] table");
}

TEST(TomlReader, AMissingFileIsNamedWithWhatItIs) {
  strut::test::TempDir dir;
  const std::string path = dir.file("absent.toml");
  EXPECT_EQ(ErrorOf([&] { Reader::ReadFile(path, "the channel file"); }), path + ": cannot open the channel file");
  std::ofstream(dir.file("present.toml")) << "a = 1\n";
  EXPECT_EQ(Reader::ReadFile(dir.file("present.toml"), "the channel file"), "a = 1\n");
}

// The four readers give the same message for the same mistake, in their own error type.
TEST(TomlReader, EveryFileOfTheProjectReadsThroughIt) {
  const std::string expected = ": [force] upper: expected a number, got the string \"lots\"";
  try {
    strut::rig::ParseSafetyConfig("[force]\nupper = \"lots\"\n", "limits.toml");
    FAIL() << "no error";
  } catch (const strut::rig::SafetyError& e) {
    EXPECT_EQ(std::string(e.what()), "limits.toml:2" + expected);
  }
  try {
    strut::sim::ParseTruth("[actuator]\nloop_bandwidth = \"lots\"\n", "truth.toml");
    FAIL() << "no error";
  } catch (const strut::sim::TruthError& e) {
    EXPECT_EQ(std::string(e.what()), "truth.toml:2: [actuator] loop_bandwidth: expected a number, got the string \"lots\"");
  }
  try {
    strut::qc::ParseNominalFile("[friction]\nupper = \"lots\"\n", "ref.toml");
    FAIL() << "no error";
  } catch (const strut::qc::ReferenceError& e) {
    EXPECT_EQ(std::string(e.what()), "ref.toml:2: [friction] upper: expected a number, got the string \"lots\"");
  }
  try {
    strut::rig::ParseMatrix("sample_rate = \"lots\"\n", "matrix.toml");
    FAIL() << "no error";
  } catch (const strut::rig::MatrixFileError& e) {
    EXPECT_EQ(std::string(e.what()), "matrix.toml:1: sample_rate: expected a number, got the string \"lots\"");
  }
}

}  // namespace
