// The shaker test matrix: sinusoidal stroke set-points around static positions.
#pragma once

#include <string>
#include <vector>

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

}  // namespace strut::rig
