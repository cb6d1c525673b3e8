// The QC matrix the rig runs for production QC (docs/qc.md): four experiments, about 2.5 minutes
// with settling, and its matrix file for `strut rig run --matrix`.
#pragma once

#include <string>
#include <vector>

#include "strut/rig/test_matrix.h"

namespace strut::qc {

inline constexpr double kQcSampleRate = 200.0;  //!< Hz
inline constexpr long kQcPeriods = 3;           //!< recorded steady-state periods per experiment

//! The QC matrix's experiments (docs/qc.md gives the reasoning for each).
std::vector<rig::MatrixEntry> QcExperiments();

//! The QC matrix as a matrix file (TOML, docs/simulated-rig.md "Matrix files"), each line of
//! `comment` as a leading comment.
std::string QcMatrixFileText(const std::string& comment);

}  // namespace strut::qc
