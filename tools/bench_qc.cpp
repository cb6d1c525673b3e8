// strut bench qc: the production-lot study of docs/qc.md (study::RunLotStudy): the confusion matrix
// (true kind against PASS / FAIL / UNDECIDED), whether a failed defect names its quantity, the
// coverage of the quantities' 95 % intervals, and the decision time.
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <iostream>
#include <nlohmann/json.hpp>

#include "bench_options.h"
#include "commands.h"
#include "option_checks.h"
#include "output_files.h"
#include "qc_commands.h"
#include "strut/study/cpu_time.h"
#include "strut/study/lot.h"

namespace strut::tools {
namespace {

void PrintUnit(const study::LotUnitResult& u) {
  if (!u.rig_error.empty())
    spdlog::warn("unit {} ({}): the rig could not run the QC matrix: {}", u.seed, study::ToString(u.kind), u.rig_error);
  std::cout << study::LotUnitLine(u);
}

nlohmann::json UnitJson(const study::LotUnitResult& u) {
  const qc::Decision& d = u.decision;
  nlohmann::json z = nlohmann::json::object();
  for (const auto& [name, value] : u.z) z[name] = value;
  return {{"seed", u.seed},
          {"kind", study::ToString(u.kind)},
          {"verdict", qc::ToString(d.verdict)},
          {"out", fmt::format("{}", fmt::join(u.out, ", "))},
          {"guard_band", fmt::format("{}", fmt::join(u.guard_band, ", "))},
          {"seconds", d.seconds},
          {"cpu_seconds", u.cpu_seconds},
          {"fit_verdict", d.fit_verdict},
          {"reasons", d.reasons},
          {"z", z}};
}

struct BenchQc {
  study::LotOptions options;
  int truth_ranges = 0;
  std::string json_path;

  void Ranges() const {
    std::cout << fmt::format("true quantities of {} good lot units (seeds {}..):\n", truth_ranges, options.first_seed);
    for (const study::QuantityRange& r : study::TrueQuantityRanges(truth_ranges, options.first_seed))
      std::cout << fmt::format("  {:<22} {:12.5g} .. {:12.5g}\n", r.name, r.low, r.high);
  }

  void Run() const {
    CheckOutputPath("--json", json_path, {});
    if (truth_ranges > 0) return Ranges();
    std::cout << study::LotHeading(options);
    const study::LotStudy s = study::RunLotStudy(options, PrintUnit);
    std::cout << study::LotSummary(s);
    nlohmann::json cj = nlohmann::json::object(), cov = nlohmann::json::object();
    for (const auto& k : s.kinds) {
      const std::map<std::string, long>& row = s.confusion.at(k);
      cj[k] = {{"PASS", row.at("PASS")}, {"FAIL", row.at("FAIL")}, {"UNDECIDED", row.at("UNDECIDED")}};
    }
    for (const auto& [name, c] : s.coverage) cov[name] = {{"inside", c.first}, {"total", c.second}};
    if (json_path.empty()) return;
    nlohmann::json rows = nlohmann::json::array();
    for (const study::LotUnitResult& u : s.units) rows.push_back(UnitJson(u));
    WriteJsonOutput(json_path, nlohmann::json{{"units", rows},
                                              {"confusion", cj},
                                              {"defects_passed", s.defects_passed},
                                              {"good_failed", s.good_failed},
                                              {"good", s.good},
                                              {"defects", s.defects},
                                              {"coverage", cov},
                                              {"median_decision_seconds", s.median_wall},
                                              {"median_decision_cpu_seconds", s.median_cpu}});
  }
};

}  // namespace

void RegisterBenchQc(CLI::App& bench) {
  auto [sub, command] = AddCommand<BenchQc>(
      bench, "qc",
      "The QC lot study: drawn units, some defective, each through the QC matrix and decided; confusion matrix "
      "and decision time (docs/qc.md).");
  AddDrawnUnitsOptions(*sub, command->options, "Units in the lot.", 100000);
  sub->add_option("--defects", command->options.defect_tenths, "Defective units per ten (the defect kinds take turns).")
      ->check(Between(0, 10))
      ->capture_default_str();
  sub->add_option("--truth-ranges", command->truth_ranges,
                  "Only draw this many good units and print the range of their true quantities (the lot reference's "
                  "bands come from it).");
  sub->add_flag("--servo", command->options.servo,
                "Drive the units through the rig's servo actuator (default: an ideal actuator, docs/qc.md).");
  sub->add_option("--json", command->json_path, "Also write the figures as JSON to this file.");
}

}  // namespace strut::tools
