// The shaker test matrix: sinusoidal stroke set-points around static positions, and the matrix
// files that give one (TOML, docs/simulated-rig.md "Matrix files").
#pragma once

#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "strut/daq/session.h"

namespace strut::rig {

//! One sinusoidal experiment of a test matrix (SI units).
struct MatrixEntry {
  std::string label;             //!< "a".."n" in the standard matrix
  std::string group;             //!< static-position group: "high", "middle", "low"
  double frequency = 0.0;        //!< Hz
  double static_position = 0.0;  //!< m, compression-positive
  double amplitude = 0.0;        //!< m
};

//! The 14-experiment standard matrix of method.md (paper Tables 1 and 2).
std::vector<MatrixEntry> StandardMatrix();

//! The periodic experiment that runs `entry`, without samples: its label, group, frequency,
//! static position and amplitude, with `periods` steady periods at `sample_rate`.
daq::Experiment PeriodicExperimentOf(const MatrixEntry& entry, long periods, double sample_rate);

//! A test matrix with optional overrides of the acquisition (from a matrix file).
struct MatrixPlan {
  std::string source = "<standard matrix>";
  std::vector<MatrixEntry> experiments;
  std::optional<double> sample_rate;  //!< Hz, overrides the rig's (a simulated rig's truth's) sample rate
  std::optional<long> periods;        //!< overrides the periods recorded per experiment
};

//! A matrix file that cannot be read or is malformed; what() names the file and line.
class MatrixFileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

//! StandardMatrix() (the 14 experiments of method.md).
MatrixPlan StandardMatrixPlan();
//! Reads a matrix file. Throws MatrixFileError naming the file and line.
MatrixPlan ReadMatrixFile(const std::string& path);
//! The matrix file's text as it is (a session keeps it); MatrixFileError when it cannot be opened.
std::string ReadMatrixText(const std::string& path);
//! A matrix file's text; `source_name` names it in errors and becomes the plan's source.
MatrixPlan ParseMatrix(std::string_view text, const std::string& source_name);
//! The matrix file (TOML) of a plan, each line of `comment` as a leading comment; ParseMatrix reads
//! it back to the same plan (numbers written to round-trip).
std::string MatrixFileText(const MatrixPlan& plan, const std::string& comment);

}  // namespace strut::rig
