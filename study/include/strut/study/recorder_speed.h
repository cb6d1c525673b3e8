// The streaming recorder's throughput (`strut bench recorder`, docs/recording.md "Figures"): as a
// ratio to raw sequential writes of the same bytes on the same disk, and its CPU per sample.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "strut/daq/recorder.h"

namespace strut::study {

struct RecorderSpeedOptions {
  double seconds = 20.0;  //!< of data
  double rate = 50000.0;  //!< Hz
  int channels = 4;       //!< SI channels, each with raw counts
  double block_ms = 10.0;  //!< block length handed over per Append
  int repeats = 3;
  std::string folder;  //!< where the files go (an existing directory)
};

//! One way of writing the bytes, medians over the repeats.
struct WriteFigure {
  std::string name;
  double wall = 0.0;  //!< s
  double cpu = 0.0;   //!< s of the whole process
  double bytes = 0.0;
};

struct RecorderSpeedStudy {
  std::size_t samples = 0;
  std::uint64_t journal_bytes = 0;
  double session_bytes = 0.0;
  //! Raw write(2) with fdatasync at the recorder's interval, with one fdatasync at the end, the
  //! recorder's streaming, its Close (journal to HDF5 session) and the two together.
  std::vector<WriteFigure> figures;
  daq::RecorderStats last;  //!< of the last recorder run
  double core_share = 0.0;  //!< of one core, streaming at `rate` in real time
};

RecorderSpeedStudy RunRecorderSpeed(const RecorderSpeedOptions& options);

}  // namespace strut::study
