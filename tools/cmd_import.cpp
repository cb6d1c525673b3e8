// strut import: measured records (CSV, MAT) into generic session files (docs/silverbox.md,
// docs/session-files.md "Generic sessions").
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <iostream>

#include "commands.h"
#include "option_checks.h"
#include "output_files.h"
#include "strut/daq/session.h"
#include "strut/daq/import.h"

namespace strut::tools {
namespace {

struct ImportCommand {
  std::string format;  // "csv" or "mat"
  std::string file, out;
  std::string preset;
  std::vector<std::string> columns, periodic, records, variables;
  double sample_rate = 0.0;
  std::string input, serial, rig;
  int gzip = 4;
  bool force = false;

  void Run() const {
    daq::ImportSpec spec;
    if (preset == "silverbox") spec = daq::ImportSpec::Silverbox();
    if (!columns.empty()) {
      spec.columns.clear();
      for (const auto& c : columns) spec.columns.push_back(daq::ColumnMapping::Parse(c));
    }
    if (!periodic.empty()) {
      spec.periodic.clear();
      for (const auto& p : periodic) spec.periodic.push_back(daq::PeriodicSegments::Parse(p));
    }
    if (!records.empty()) {
      spec.records.clear();
      for (const auto& r : records) spec.records.push_back(daq::RecordSegment::Parse(r));
    }
    if (sample_rate > 0) spec.sample_rate = sample_rate;
    if (!input.empty()) spec.input_channel = input;
    if (!serial.empty()) spec.serial = serial;
    if (!rig.empty()) spec.rig = rig;
    if (spec.columns.empty())
      throw daq::ImportError(fmt::format("{}: map at least one column (--column u=V1:V) or use --preset", file));
    if (!(spec.sample_rate > 0)) throw daq::ImportError(fmt::format("{}: give --sample-rate (Hz)", file));

    CheckOutputPath("--out", out, {file}, force);
    std::vector<std::string> wanted = variables;
    if (format == "mat" && wanted.empty())
      for (const auto& c : spec.columns) wanted.push_back(c.column);
    const daq::Record record = format == "mat" ? daq::ReadMatRecord(file, wanted) : daq::ReadCsvRecord(file);
    spdlog::info("{}: {} columns ({}), {} rows", file, record.names.size(), fmt::join(record.names, ", "), record.rows());
    const daq::Session session = daq::BuildSession(record, spec);
    daq::WriteOptions options;
    options.gzip_level = gzip;
    daq::WriteSession(out, session, options);

    std::cout << fmt::format("{} -> {} (profile generic, {} experiments)\n", file, out, session.experiments.size());
    std::cout << fmt::format("{:<8} {:<9} {:>9} {:>12} {:>10}  {}\n", "label", "kind", "samples", "first sample",
                             "f [Hz]", "channels");
    for (const auto& e : session.experiments) {
      std::string channels;
      for (const auto& c : e.channels) channels += fmt::format("{}[{}] ", c.name, c.units);
      std::cout << fmt::format("{:<8} {:<9} {:>9} {:>12} {:>10}  {}\n", e.label, daq::ToString(e.kind), e.sample_count(),
                               e.extra_attributes.count("first_sample") ? e.extra_attributes.at("first_sample") : "-",
                               e.kind == daq::ExperimentKind::kPeriodic ? fmt::format("{:.6g}", e.frequency) : "-",
                               channels);
    }
  }
};

void AddFormat(CLI::App& parent, const std::string& format, const std::string& help) {
  auto [sub, command] = AddCommand<ImportCommand>(parent, format, help);
  command->format = format;
  sub->add_option("file", command->file, "The measured record to import.")->required()->check(CLI::ExistingFile);
  sub->add_option("-o,--out", command->out, "Session file to write (HDF5).")->required();
  sub->add_flag("--force", command->force, "Replace an existing session file at the output path.");
  sub->add_option("--preset", command->preset, "Use the column mapping, sample rate and segmentation of a known record.")
      ->check(CLI::IsMember({"silverbox"}));
  sub->add_option("--column", command->columns, "Map a column to a channel: CHANNEL=COLUMN[:UNITS[:SCALE]], e.g. u=V1:V. Repeat for several channels.");
  sub->add_option("--sample-rate", command->sample_rate, "The sample rate in Hz.")->check(Positive("Hz"));
  sub->add_option("--input", command->input, "The channel that excites the system (stored as the session's 'excitation').");
  sub->add_option("--periodic", command->periodic,
                  "Periodic experiments: prefix=ms,start=40986,period=8192[,periods=1][,count=10][,stride=8692]"
                  "[,waveform=multisine][,group=G], in 0-based samples. Repeat for several series.");
  sub->add_option("--record", command->records, "A free record LABEL=START:END in 0-based samples, END excluded. Repeat for several records.");
  if (format == "mat")
    sub->add_option("--variables", command->variables, "The MAT variables to read (default: the mapped columns).")
        ->delimiter(',');
  sub->add_option("--serial", command->serial, "The unit under test, stored as damper_serial.");
  sub->add_option("--rig", command->rig, "Where the record comes from, stored as rig.");
  sub->add_option("--gzip", command->gzip, "The HDF5 gzip compression level.")->check(Between(0, 9))->capture_default_str();
}

}  // namespace

void RegisterImportCommand(CLI::App& app) {
  CLI::App* import = app.add_subcommand("import", "Import measured records (CSV, MAT) into session files of the generic profile (docs/session-files.md).");
  import->require_subcommand(1);
  AddFormat(*import, "csv", "Import a CSV file whose first line names the columns.");
  AddFormat(*import, "mat", "Import a MATLAB MAT file (read with libmatio).");
}

}  // namespace strut::tools
