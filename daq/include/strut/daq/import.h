// Measured records from other programs (CSV, MATLAB MAT v5) turned into session files: column
// mapping, units, sample rate and the segmentation into periodic experiments (docs/silverbox.md,
// docs/session-files.md "Generic sessions").
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "strut/daq/session.h"

namespace strut::daq {

//! A file that cannot be imported. what() names the file and, where it applies, the line and
//! column (CSV), the variable (MAT) or the segment.
class ImportError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

//! Named columns of equal length, as read from a file.
struct Record {
  std::string source;                        //!< the file, for messages
  std::vector<std::string> names;            //!< column (CSV header) or variable (MAT) names
  std::vector<std::vector<double>> columns;  //!< one per name, all of rows() values

  std::size_t rows() const { return columns.empty() ? 0 : columns.front().size(); }
  //! The column, or ImportError naming the file and the columns it has.
  const std::vector<double>& column(std::string_view name) const;
};

//! Reads a CSV file with a header line of column names. Lenient where writers differ: quoted
//! names, a trailing delimiter (an empty last field), blank lines, CRLF, comma, semicolon or tab
//! delimiters. A column that is empty below its first row (a constant written once, like the
//! Silverbox Ovld flags or the F-16 `Fs`) is dropped with a debug line. Any other empty or
//! non-numeric field is an ImportError naming the file, line and column.
Record ReadCsvRecord(const std::string& path);

//! Reads the numeric vectors (1 x N or N x 1, any real class) of a MATLAB MAT file through libmatio
//! (v4, v5 compressed or not, v7.3). Scalars and other variables are skipped with a debug line
//! unless named in `variables`. With `variables` given, exactly those are read (an ImportError names
//! a missing or non-vector one). Vectors of different lengths are an ImportError naming them.
Record ReadMatRecord(const std::string& path, const std::vector<std::string>& variables = {});

//! Reads a CSV (.csv, .txt) or MAT (.mat) file by its extension.
Record ReadRecord(const std::string& path);

//! One session channel from one record column: samples * scale, in `units`.
struct ColumnMapping {
  std::string channel;  //!< session channel name, e.g. "u"
  std::string column;   //!< record column / variable, e.g. "V1"
  std::string units;    //!< SI symbol the session accepts, e.g. "V"
  double scale = 1.0;   //!< samples are multiplied by this (e.g. 1e-3 for mV recorded, V wanted)

  //! Parses "CHANNEL=COLUMN[:UNITS[:SCALE]]" (the --column option). Throws ImportError.
  static ColumnMapping Parse(std::string_view text);
};

//! `count` periodic experiments labelled PREFIX0, PREFIX1, ..., the k-th holding `periods` whole
//! periods of `period` samples from `start + k * stride` (0-based sample index). Each is excited
//! by the measured input (waveform names the excitation, e.g. "multisine").
struct PeriodicSegments {
  std::string prefix = "p";
  long start = 0;
  long period = 0;       //!< samples per period
  long periods = 1;      //!< whole steady-state periods per experiment
  long count = 1;        //!< experiments
  long stride = 0;       //!< samples from one experiment's start to the next (0: back to back)
  std::string waveform = "measured";
  std::string group;

  //! Parses "prefix=ms,start=40986,period=8192[,periods=1][,count=10][,stride=8692]
  //! [,waveform=multisine][,group=...]" (the --periodic option). Throws ImportError.
  static PeriodicSegments Parse(std::string_view text);
};

//! A free record (kind "record") of samples [start, end), e.g. a test signal.
struct RecordSegment {
  std::string label;
  long start = 0, end = 0;

  //! Parses "LABEL=START:END" (the --record option). Throws ImportError.
  static RecordSegment Parse(std::string_view text);
};

//! Everything that turns a record into a session.
struct ImportSpec {
  std::vector<ColumnMapping> columns;
  double sample_rate = 0.0;     //!< Hz
  std::string input_channel;    //!< the excitation (stored as the experiments' `excitation`); may be empty
  std::vector<PeriodicSegments> periodic;
  std::vector<RecordSegment> records;
  std::string serial = "unknown";  //!< the session's damper_serial: the unit under test
  std::string rig = "imported";

  //! The Silverbox benchmark (data README §2, SNLS80mV): u = V1, y = V2 in volts,
  //! fs = 10^7 / 2^14 Hz; the ten steady-state periods of 8192 samples, experiments ms0..ms9 at
  //! 40986 + 8692 k; the arrow as the record "arrow" [86, 40486); the zeros before it as the
  //! record "zeros" [0, 86).
  static ImportSpec Silverbox();
};

//! Builds a generic-profile session (docs/session-files.md) from a record. Throws ImportError
//! naming the file for a missing column, a segment outside the record, overlapping labels or
//! a bad sample rate; the session validates (daq::Validate) when this returns.
daq::Session BuildSession(const Record& record, const ImportSpec& spec);

}  // namespace strut::daq
