// strut bench qc: the production-lot study of docs/qc.md. Units drawn with the simulated rig's
// manufacturing scatter (qc::LotUnit), a fixed fraction made defective (qc::MakeDefective), each run
// through the QC matrix on the simulated rig and decided against the lot's reference: the confusion
// matrix (true kind against PASS / FAIL / UNDECIDED), whether a failed defect names its quantity,
// the coverage of the quantities' 95 % intervals, and the decision time.
#include <spdlog/spdlog.h>
#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "qc_commands.h"
#include "output_files.h"
#include "strut/qc/decision.h"
#include "bench_support.h"
#include "strut/qc/lot.h"
#include "option_checks.h"

namespace strut::tools {
namespace {

//! The quantity a defect changes (the one a FAIL must name).
const char* QuantityOf(qc::Defect d) {
  switch (d) {
    case qc::Defect::kUnderCharge: return "charge_pressure";
    case qc::Defect::kExcessFriction: return "friction";
    case qc::Defect::kOilOverfill:
    case qc::Defect::kLowOil: return "gas_column";
    case qc::Defect::kHighOrifice: return "orifice_damping";
    case qc::Defect::kLeakingSeal: return "viscous_damping";
    case qc::Defect::kNone: return "";
  }
  return "";
}

struct BenchQc {
  int units = 200;
  unsigned long first_seed = 5000;
  int defect_tenths = 3;  // defective units per ten
  int truth_ranges = 0;
  bool servo = false;
  std::string json_path;

  //! Unit i is defective when i % 10 < defect_tenths; the defects take turns.
  qc::Defect KindOf(int i) const {
    if (i % 10 >= defect_tenths) return qc::Defect::kNone;
    const int k = (i / 10) * defect_tenths + i % 10;
    return qc::Defects()[k % qc::Defects().size()];
  }

  void Ranges() const {
    std::map<std::string, std::pair<double, double>> range;
    std::vector<std::string> order;
    for (int i = 0; i < truth_ranges; ++i) {
      const sim::Truth unit = qc::LotUnit(first_seed + i);
      const ident::Model model = unit.BuildModel(ident::Causality::kStrokeInput);
      for (const qc::Quantity& q : qc::ComputeQuantities(model, unit.Parameters(model).values())) {
        if (!range.count(q.name)) {
          range[q.name] = {q.value, q.value};
          order.push_back(q.name);
        }
        range[q.name].first = std::min(range[q.name].first, q.value);
        range[q.name].second = std::max(range[q.name].second, q.value);
      }
    }
    std::cout << fmt::format("true quantities of {} good lot units (seeds {}..):\n", truth_ranges, first_seed);
    for (const auto& n : order)
      std::cout << fmt::format("  {:<22} {:12.5g} .. {:12.5g}\n", n, range[n].first, range[n].second);
  }

  void Run() const {
    CheckOutputPath("--json", json_path, {});
    if (truth_ranges > 0) return Ranges();
    const qc::Reference reference = qc::LotReference();
    const rig::MatrixPlan plan = qc::QcMatrix();
    std::vector<std::string> kinds = {"good"};
    for (qc::Defect d : qc::Defects()) kinds.push_back(qc::ToString(d));
    std::map<std::string, std::map<std::string, long>> confusion;
    std::map<std::string, long> named_right;
    std::map<std::string, std::pair<long, long>> coverage;  // quantity: inside, total
    std::vector<double> wall, cpu, sim_seconds;
    long guard_band = 0;
    nlohmann::json rows = nlohmann::json::array();
    double load[1] = {NAN};
    getloadavg(load, 1);
    std::cout << fmt::format("QC of a simulated lot: {} units (seeds {}..), {} in 10 defective, QC matrix of {} "
                             "experiments, reference {}, {} actuator; load average {:.2f} at the start\n",
                             units, first_seed, defect_tenths, plan.experiments.size(), reference.source,
                             servo ? "servo" : "ideal", load[0]);
    for (int i = 0; i < units; ++i) {
      const unsigned long seed = first_seed + i;
      const qc::Defect kind = KindOf(i);
      sim::Truth truth = qc::MakeDefective(qc::LotUnit(seed), kind, reference, seed);
      if (servo) truth.actuator.ideal = false;
      const sim::SimulatedRig rig(truth);
      sim::RigRunOptions run;
      run.seed = seed;
      const auto sim_start = std::chrono::steady_clock::now();
      daq::Session session;
      try {
        session = rig.RunMatrix(plan, run);
      } catch (const std::exception& e) {
        spdlog::warn("unit {} ({}): the rig could not run the QC matrix: {}", seed, qc::ToString(kind), e.what());
      }
      sim_seconds.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - sim_start).count());
      const double before = ThreadSeconds();
      const qc::Decision d = qc::RunQc(session, truth.damper_serial, reference);
      cpu.push_back(ThreadSeconds() - before);
      wall.push_back(d.seconds);
      const std::string verdict = qc::ToString(d.verdict);
      ++confusion[qc::ToString(kind)][verdict];
      std::string failed, guarded;
      bool named = false;
      for (const auto& q : d.quantities) {
        if (q.status == qc::Status::kOut || q.status == qc::Status::kGuardBand) {
          failed += (failed.empty() ? "" : ", ") + q.quantity.name;
          named = named || q.quantity.name == QuantityOf(kind);
          if (q.status == qc::Status::kGuardBand) {
            ++guard_band;
            guarded += (guarded.empty() ? "" : ", ") + q.quantity.name;
          }
        }
      }
      if (kind != qc::Defect::kNone && d.verdict == qc::Verdict::kFail && named) ++named_right[qc::ToString(kind)];
      // The truth's place in the 95 % intervals (a fit at the noise floor only).
      nlohmann::json z = nlohmann::json::object();
      if (d.fit_verdict == "at-noise-floor") {
        const ident::Model model = truth.BuildModel(ident::Causality::kStrokeInput);
        for (const qc::Quantity& t : qc::ComputeQuantities(model, truth.Parameters(model).values()))
          for (const auto& q : d.quantities)
            if (q.quantity.name == t.name && std::isfinite(q.quantity.sd) && q.quantity.sd > 0) {
              const double zz = (q.quantity.value - t.value) / q.quantity.sd;
              z[t.name] = zz;
              coverage[t.name].first += std::abs(zz) < qc::kGuardBandSigmas;
              coverage[t.name].second += 1;
            }
      }
      std::cout << fmt::format("  unit {:5} {:<16} {:<9} {:5.2f} s{}{}{}\n", seed, qc::ToString(kind), verdict,
                               d.seconds, failed.empty() ? "" : "  out: " + failed,
                               guarded.empty() ? "" : " (guard band: " + guarded + ")",
                               d.verdict == qc::Verdict::kUndecided && !d.reasons.empty() ? "  (" + d.reasons.front() + ")"
                                                                                           : "");
      rows.push_back({{"seed", seed}, {"kind", qc::ToString(kind)}, {"verdict", verdict}, {"out", failed}, {"guard_band", guarded},
                      {"seconds", d.seconds}, {"cpu_seconds", cpu.back()}, {"fit_verdict", d.fit_verdict},
                      {"reasons", d.reasons}, {"z", z}});
    }
    const auto median = [](std::vector<double> v) {
      std::sort(v.begin(), v.end());
      return v.empty() ? NAN : v[v.size() / 2];
    };
    std::cout << fmt::format("\nconfusion matrix (true kind: decisions):\n  {:<16} {:>5} {:>5} {:>9} {:>6}  {}\n", "kind",
                             "PASS", "FAIL", "UNDECIDED", "total", "FAIL naming the defect's quantity");
    nlohmann::json cj = nlohmann::json::object();
    long defects_passed = 0, defects = 0, good_failed = 0, good = 0;
    for (const auto& k : kinds) {
      auto& row = confusion[k];
      const long total = row["PASS"] + row["FAIL"] + row["UNDECIDED"];
      std::cout << fmt::format("  {:<16} {:>5} {:>5} {:>9} {:>6}  {}\n", k, row["PASS"], row["FAIL"], row["UNDECIDED"],
                               total, k == "good" ? "" : std::to_string(named_right[k]) + "/" + std::to_string(row["FAIL"]));
      cj[k] = {{"PASS", row["PASS"]}, {"FAIL", row["FAIL"]}, {"UNDECIDED", row["UNDECIDED"]}};
      if (k == "good") {
        good += total;
        good_failed += row["FAIL"];
      } else {
        defects += total;
        defects_passed += row["PASS"];
      }
    }
    std::cout << fmt::format(
        "defective units passed: {}/{} (target 0); good units failed: {}/{} = {:.1f} % (target < 3 %); guard-band "
        "decisions {}\n",
        defects_passed, defects, good_failed, good, good ? 100.0 * good_failed / good : 0.0, guard_band);
    std::cout << "95 % intervals of the quantities holding the truth (fits at the noise floor):\n";
    nlohmann::json cov = nlohmann::json::object();
    for (const auto& [name, c] : coverage) {
      std::cout << fmt::format("  {:<22} {}/{} = {:.3f}\n", name, c.first, c.second, double(c.first) / c.second);
      cov[name] = {{"inside", c.first}, {"total", c.second}};
    }
    std::cout << fmt::format(
        "decision time (read session to verdict: prepare, fit, quantities, decide): median {:.3f} s wall, {:.3f} s CPU "
        "on one thread, max {:.3f} s wall (target < 1 s); rig simulation median {:.2f} s wall per unit\n",
        median(wall), median(cpu), *std::max_element(wall.begin(), wall.end()), median(sim_seconds));
    if (!json_path.empty())
      WriteTextOutput(json_path, nlohmann::json{{"units", rows},
                                                {"confusion", cj},
                                                {"defects_passed", defects_passed},
                                                {"good_failed", good_failed},
                                                {"good", good},
                                                {"defects", defects},
                                                {"coverage", cov},
                                                {"median_decision_seconds", median(wall)},
                                                {"median_decision_cpu_seconds", median(cpu)}}
                                         .dump(1) + "\n");
  }
};

}  // namespace

void RegisterBenchQc(CLI::App& bench) {
  auto command = std::make_shared<BenchQc>();
  CLI::App* sub = bench.add_subcommand(
      "qc", "The QC lot study: drawn units, some defective, each through the QC matrix and decided; confusion matrix "
            "and decision time (docs/qc.md).");
  sub->add_option("--units", command->units, "Units in the lot.")->check(Between(1, 100000))->capture_default_str();
  sub->add_option("--first-seed", command->first_seed, "Seed of the first unit (the others follow).")->capture_default_str();
  sub->add_option("--defects", command->defect_tenths, "Defective units per ten (the defect kinds take turns).")
      ->check(Between(0, 10))
      ->capture_default_str();
  sub->add_option("--truth-ranges", command->truth_ranges,
                  "Only draw this many good units and print the range of their true quantities (the lot reference's "
                  "bands come from it).");
  sub->add_flag("--servo", command->servo,
                "Drive the units through the rig's servo actuator (default: an ideal actuator, docs/qc.md).");
  sub->add_option("--json", command->json_path, "Also write the figures as JSON to this file.");
  sub->callback([command] { command->Run(); });
}

}  // namespace strut::tools
