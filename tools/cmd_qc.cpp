// strut qc: production quality control of a damper from a short QC session (docs/qc.md).
//   strut qc SESSION.h5 --reference REF [--json OUT] [--report OUT.html] [--db FILE]
//   strut qc plan [-o FILE] [--write-reference FILE]
//   strut qc history --db FILE [--serial S] [--since DATE] [--json]
#include <spdlog/spdlog.h>

#include <cmath>
#include <filesystem>
#include <iostream>
#include <map>
#include <optional>

#include "commands.h"
#include "qc_commands.h"
#include "output_files.h"
#include "strut/report/qc_report.h"
#include "strut/qc/decision.h"
#include "strut/qc/history.h"
#include "strut/qc/matrix.h"
#include "strut/study/lot.h"

namespace strut::tools {
namespace {

struct PlanCommand {
  std::string output, reference_output;
  void Run() const {
    CheckOutputPath("-o", output, {});
    CheckOutputPath("--write-reference", reference_output, {});
    if (!output.empty() && output == reference_output)
      throw std::invalid_argument("-o and --write-reference name the same file " + output);
    const std::string text = qc::QcMatrixFileText(
        "The QC matrix of strut (docs/qc.md): four experiments, about 2.5 minutes on the rig with settling.\n"
        "Run it with `strut rig run --matrix FILE` (or `strut sim matrix --matrix FILE`), then\n"
        "`strut qc SESSION.h5 --reference REF`.");
    if (output.empty())
      std::cout << text;
    else
      WriteTextOutput(output, text);
    if (!reference_output.empty()) WriteTextOutput(reference_output, std::string(study::LotReferenceText()));
  }
};

struct HistoryCommand {
  std::string db_path;
  std::optional<std::string> serial, since;
  bool json = false;
  void Run() const {
    if (!qc::IsPostgresUrl(db_path) && !std::filesystem::exists(db_path))
      throw std::invalid_argument("--db " + db_path + ": no such QC history");
    const qc::History history(db_path);
    const std::vector<qc::HistoryEntry> entries = history.Query(serial, since);
    const std::vector<qc::QuantityTrend> trends = qc::Trends(entries);
    const auto number = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); };
    if (json) {
      nlohmann::json j{{"decisions", nlohmann::json::array()}, {"trends", nlohmann::json::array()}};
      std::map<std::string, long> counts;
      for (const auto& e : entries) {
        ++counts[e.verdict];
        nlohmann::json q = nlohmann::json::array();
        for (const auto& x : e.quantities)
          q.push_back({{"name", x.quantity.name}, {"unit", x.quantity.unit}, {"value", number(x.quantity.value)},
                       {"sd", number(x.quantity.sd)}, {"nominal", number(x.nominal)}, {"lower", number(x.lower)},
                       {"upper", number(x.upper)}, {"status", qc::ToString(x.status)}, {"meaning", x.meaning}});
        j["decisions"].push_back({{"id", e.id}, {"serial", e.serial}, {"time", e.time}, {"session", e.session},
                                  {"reference", e.reference}, {"model", e.model}, {"verdict", e.verdict},
                                  {"reasons", e.reasons}, {"quantities", q}});
      }
      for (const auto& t : trends)
        j["trends"].push_back({{"name", t.name}, {"unit", t.unit}, {"count", t.count}, {"mean", number(t.mean)},
                               {"sd", number(t.sd)}, {"min", number(t.min)}, {"max", number(t.max)},
                               {"first", number(t.first)}, {"last", number(t.last)},
                               {"slope_per_day", number(t.slope_per_day)}, {"out_of_band", t.out_of_band}});
      j["counts"] = counts;
      std::cout << j.dump(1) << "\n";
      return;
    }
    long pass = 0, fail = 0, undecided = 0;
    std::cout << fmt::format("{:>5}  {:<20}  {:<20}  {:<9}  {}\n", "id", "time", "serial", "verdict", "first reason");
    for (const auto& e : entries) {
      pass += e.verdict == "PASS";
      fail += e.verdict == "FAIL";
      undecided += e.verdict == "UNDECIDED";
      std::cout << fmt::format("{:>5}  {:<20}  {:<20}  {:<9}  {}\n", e.id, e.time, e.serial, e.verdict,
                               e.reasons.empty() ? "" : e.reasons.front());
    }
    std::cout << fmt::format("{} decisions: {} PASS, {} FAIL, {} UNDECIDED\n", entries.size(), pass, fail, undecided);
    if (trends.empty()) return;
    std::cout << fmt::format("\ntrends per quantity:\n  {:<22} {:>5} {:>12} {:>10} {:>12} {:>12} {:>12} {:>14} {:>6}\n",
                             "quantity", "n", "mean", "sd", "min", "max", "last", "slope per day", "out");
    for (const auto& t : trends)
      std::cout << fmt::format("  {:<22} {:>5} {:>12.5g} {:>10.3g} {:>12.5g} {:>12.5g} {:>12.5g} {:>14.3g} {:>6}\n",
                               t.name, t.count, t.mean, t.sd, t.min, t.max, t.last, t.slope_per_day, t.out_of_band);
  }
};

}  // namespace

QcOutcome QcCommand::Decide() const {
  if (session.empty()) throw std::invalid_argument("qc: give a session (strut qc SESSION.h5 --reference REF)");
  if (reference.empty()) throw std::invalid_argument("qc: --reference REF is required (a golden unit's identify JSON or a nominal file)");
  // Before any work: outputs writable, never an input; the history opens (or is created) now.
  const std::vector<std::string> inputs{session, reference};
  CheckOutputPath("--json", json_path, inputs);
  CheckOutputPath("--report", report_path, inputs);
  if (!qc::IsPostgresUrl(db_path)) CheckOutputPath("--db", db_path, inputs);
  if (!json_path.empty() && json_path == report_path)
    throw std::invalid_argument("--json and --report name the same file " + json_path);
  if (!time.empty() && db_path.empty()) throw std::invalid_argument("--time is the decision's time in the history: give --db too");
  if (!time.empty() && !qc::IsUtcTime(time))
    throw std::invalid_argument("--time '" + time + "': give a UTC time YYYY-MM-DDTHH:MM:SSZ");
  const qc::Reference ref = qc::ReadReference(reference);
  std::optional<qc::History> history;
  if (!db_path.empty()) history.emplace(db_path);

  QcOutcome outcome;
  outcome.decision = qc::RunQc(session, ref, &outcome.fit);
  const qc::Decision& d = outcome.decision;
  if (!json_path.empty()) WriteJsonOutput(json_path, report::QcToJson(d));
  if (!report_path.empty()) {
    report::WriteQcReport(d, d.fit_verdict.empty() ? nullptr : &outcome.fit, report_path);
    spdlog::info("wrote {}", report_path);
  }
  if (history) {
    const qc::Recorded r = history->Record(d, time);
    spdlog::info("recorded decision {} for serial {} in {}", r.id, d.serial, history->where());
  }
  return outcome;
}

void QcCommand::Run() const {
  qc::Decision d;
  try {
    d = Decide().decision;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    spdlog::error("UNDECIDED: QC could not run");
    throw ExitCode(qc::ExitCodeOf(qc::Verdict::kUndecided));
  }
  std::cout << qc::Table(d);
  switch (d.verdict) {
    case qc::Verdict::kPass: spdlog::info("PASS"); break;
    case qc::Verdict::kFail: spdlog::warn("FAIL: {}", d.reasons.empty() ? "" : d.reasons.front()); break;
    case qc::Verdict::kUndecided: spdlog::error("UNDECIDED: {}", d.reasons.empty() ? "" : d.reasons.front()); break;
  }
  if (d.verdict != qc::Verdict::kPass) throw ExitCode(qc::ExitCodeOf(d.verdict));
}

void RegisterQcCommand(CLI::App& app) {
  auto [qc, command] = AddCommand<QcCommand>(
      app, "qc",
      "Quality control of a production damper from a QC session: PASS, FAIL or UNDECIDED against a reference "
      "(docs/qc.md). Exit code 0 pass, 1 fail, 2 undecided (bad data, fit not converged or not at the noise floor).");
  AddQcOptions(*qc, *command);
  // Replaces AddCommand's callback: with `qc plan` or `qc history` only that subcommand runs.
  qc->callback([command = command, qc = qc] {
    if (qc->get_subcommands().empty()) command->Run();
  });

  auto [p, plan] =
      AddCommand<PlanCommand>(*qc, "plan", "Write the QC matrix (a matrix file for `strut sim matrix --matrix`).");
  p->add_option("-o,--output", plan->output, "Matrix file to write (default: stdout).");
  p->add_option("--write-reference", plan->reference_output,
                "Also write the simulated lot's reference file (nominal values and bands, TOML).");

  auto [h, history] = AddCommand<HistoryCommand>(*qc, "history",
                                                 "List QC decisions from the history: a lot, a serial's past results, "
                                                 "and the trend of every quantity.");
  h->add_option("--db", history->db_path, "The QC history: an SQLite file or a PostgreSQL URL (as for strut qc --db).")
      ->required();
  h->add_option("--serial", history->serial, "Only this serial.");
  h->add_option("--since", history->since, "Only decisions at or after this date (YYYY-MM-DD) or UTC time.");
  h->add_flag("--json", history->json, "Print JSON (decisions, trends, counts) instead of tables.");
}

void AddQcOptions(CLI::App& app, QcCommand& command_) {
  CLI::App* qc = &app;
  QcCommand* command = &command_;
  qc->add_option("session", command->session, "The QC session (HDF5), from the matrix `strut qc plan` writes.")
      ->check(CLI::ExistingFile);
  qc->add_option("--reference", command->reference,
                 "A golden unit's identify JSON (default bands, docs/qc.md) or a reference file of nominal values with "
                 "bands (TOML or JSON).")
      ->check(CLI::ExistingFile);
  qc->add_option("--json", command->json_path, "Write the decision as JSON.");
  qc->add_option("--report", command->report_path, "Write a self-contained HTML report.");
  qc->add_option("--db", command->db_path, "Record the decision in this QC history: an SQLite file (created when missing) or a PostgreSQL "
                 "URL postgresql://USER@HOST:PORT/DB (the password from PGPASSWORD, ~/.pgpass or a service file, "
                 "never in the URL; docs/qc.md).");
  qc->add_option("--time", command->time, "With --db: the decision's time (UTC ISO 8601) instead of now.");
}

}  // namespace strut::tools
