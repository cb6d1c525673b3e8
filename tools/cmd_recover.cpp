// strut recover: a recording cut off mid-run (crash, kill -9, power cut) into a valid session
// file (docs/recording.md "Recovery").
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <filesystem>
#include <iostream>

#include "commands.h"
#include "output_files.h"
#include "strut/daq/recorder.h"
#include "strut/daq/session.h"
#include "option_checks.h"

namespace strut::tools {
namespace {

constexpr std::string_view kJournalSuffix = ".journal";

struct RecoverCommand {
  std::string file, out;
  bool force = false;
  bool delete_journal = false;
  int gzip = 4;

  void Run() {
    namespace fs = std::filesystem;
    std::error_code ec;
    // The session's name stands for its journal when only the journal is there.
    std::string journal = file;
    if (!std::string_view(file).ends_with(kJournalSuffix) && !fs::exists(file, ec) &&
        fs::exists(daq::JournalPath(file), ec)) {
      journal = daq::JournalPath(file);
    }
    if (out.empty()) {
      if (!std::string_view(journal).ends_with(kJournalSuffix)) {
        throw std::invalid_argument(fmt::format("{}: name the session to write with -o (the journal's name does not "
                                                "end in {})",
                                                journal, kJournalSuffix));
      }
      out = journal.substr(0, journal.size() - kJournalSuffix.size());
    }
    CheckOutputPath("--out", out, {journal}, force);
    if (fs::exists(out, ec) && !force) {
      throw std::invalid_argument(fmt::format("--out {}: exists; choose another name or add --force to replace it", out));
    }
    daq::WriteOptions options;
    options.gzip_level = gzip;
    const daq::JournalReport report = daq::RecoverJournal(journal, out, force, options);
    const daq::Session session = daq::ReadSession(out);  // what was written passes the contract check

    std::cout << fmt::format("{} -> {}: {} records, {} samples, {}\n", journal, out, report.records, report.samples,
                             report.closed                  ? "the recording was closed cleanly"
                             : report.bytes_discarded == 0 ? "cut off between two records"
                                                           : fmt::format("cut off ({} bytes of a torn record discarded)",
                                                                         report.bytes_discarded));
    for (const daq::Experiment& e : session.experiments) {
      std::cout << fmt::format("  {:<10} {:<9} {:>9} samples  {}\n", e.label, e.status, e.sample_count(),
                               e.extra_attributes.count("recording_end") ? e.extra_attributes.at("recording_end") : "");
    }
    for (const std::string& label : report.dropped) {
      std::cout << fmt::format("  {:<10} not written: ended before its first sample\n", label);
    }
    if (delete_journal) {
      fs::remove(journal, ec);
      if (ec) throw std::runtime_error(fmt::format("{}: cannot delete: {}", journal, ec.message()));
      spdlog::info("deleted {}", journal);
    } else {
      spdlog::info("{} is kept; delete it once {} is checked (or recover with --delete-journal)", journal, out);
    }
  }
};

}  // namespace

void RegisterRecoverCommand(CLI::App& app) {
  auto [sub, command] = AddCommand<RecoverCommand>(
      app, "recover",
      "Turn the journal of a recording cut off mid-run into a session file (experiment in progress: aborted)");
  sub->add_option("file", command->file, "The journal (SESSION.h5.journal), or the session's name SESSION.h5.")
      ->required();
  sub->add_option("-o,--out", command->out, "Session file to write (default: the journal's name without .journal).");
  sub->add_flag("--force", command->force, "Replace an existing file at the output path.");
  sub->add_flag("--delete-journal", command->delete_journal,
                "Delete the journal once the session is written and passes the contract check.");
  sub->add_option("--gzip", command->gzip, "Compression level 0..9.")->check(Between(0, 9))->capture_default_str();
}

}  // namespace strut::tools
