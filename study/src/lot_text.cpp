// The text `strut bench qc` prints (and `strut batch` for a qc-lot job), and a unit's record.
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <nlohmann/json.hpp>

#include "strut/report/qc_report.h"
#include "strut/study/cpu_time.h"
#include "strut/study/lot.h"

namespace strut::study {

std::string LotHeading(const LotOptions& options) {
  return fmt::format("QC of a simulated lot: {} units (seeds {}..), {} in 10 defective, QC matrix of {} "
                     "experiments, reference {}, {} actuator; load average {:.2f} at the start\n",
                     options.units, options.first_seed, options.defect_tenths, QcMatrix().experiments.size(),
                     LotReference().source, options.servo ? "servo" : "ideal", LoadAverages()[0]);
}

std::string LotUnitLine(const LotUnitResult& u) {
  const qc::Decision& d = u.decision;
  const std::string failed = fmt::format("{}", fmt::join(u.out, ", ")), guarded = fmt::format("{}", fmt::join(u.guard_band, ", "));
  return fmt::format("  unit {:5} {:<16} {:<9} {:5.2f} s{}{}{}\n", u.seed, ToString(u.kind), qc::ToString(d.verdict),
                     d.seconds, failed.empty() ? "" : "  out: " + failed,
                     guarded.empty() ? "" : " (guard band: " + guarded + ")",
                     d.verdict == qc::Verdict::kUndecided && !d.reasons.empty() ? "  (" + d.reasons.front() + ")" : "");
}

std::string LotSummary(const LotStudy& s) {
  std::string text = fmt::format("\nconfusion matrix (true kind: decisions):\n  {:<16} {:>5} {:>5} {:>9} {:>6}  {}\n",
                                 "kind", "PASS", "FAIL", "UNDECIDED", "total", "FAIL naming the defect's quantity");
  for (const auto& k : s.kinds) {
    const std::map<std::string, long>& row = s.confusion.at(k);
    const long pass = row.at("PASS"), fail = row.at("FAIL"), undecided = row.at("UNDECIDED");
    const auto named = s.named_right.find(k);
    text += fmt::format("  {:<16} {:>5} {:>5} {:>9} {:>6}  {}\n", k, pass, fail, undecided, pass + fail + undecided,
                        k == "good" ? ""
                                    : fmt::format("{}/{}", named == s.named_right.end() ? 0 : named->second, fail));
  }
  text += fmt::format(
      "defective units passed: {}/{} (target 0); good units failed: {}/{} = {:.1f} % (target < 3 %); guard-band "
      "decisions {}\n",
      s.defects_passed, s.defects, s.good_failed, s.good, s.good ? 100.0 * s.good_failed / s.good : 0.0, s.guard_band);
  text += "95 % intervals of the quantities holding the truth (fits at the noise floor):\n";
  for (const auto& [name, c] : s.coverage)
    text += fmt::format("  {:<22} {}/{} = {:.3f}\n", name, c.first, c.second, double(c.first) / c.second);
  text += fmt::format(
      "decision time (read session to verdict: prepare, fit, quantities, decide): median {:.3f} s wall, {:.3f} s CPU "
      "on one thread, max {:.3f} s wall (target < 1 s); rig simulation median {:.2f} s wall per unit\n",
      s.median_wall, s.median_cpu, s.max_wall, s.median_sim);
  return text;
}

nlohmann::json LotUnitJson(const LotUnitResult& u) {
  nlohmann::json decision = report::QcToJson(u.decision);
  decision.erase("seconds");
  return {{"seed", u.seed},
          {"kind", ToString(u.kind)},
          {"decision", decision},
          {"rig_error", u.rig_error},
          {"out", u.out},
          {"guard_band", u.guard_band},
          {"named", u.named},
          {"z", u.z},
          {"timing", {{"seconds", u.decision.seconds}, {"cpu_seconds", u.cpu_seconds}, {"sim_seconds", u.sim_seconds}}}};
}

LotUnitResult LotUnitFromJson(const nlohmann::json& j) {
  LotUnitResult u;
  u.seed = j.at("seed").get<unsigned long>();
  const std::string kind = j.at("kind").get<std::string>();
  for (Defect d : Defects())
    if (kind == ToString(d)) u.kind = d;
  const nlohmann::json& d = j.at("decision");
  const std::string verdict = d.at("verdict").get<std::string>();
  for (qc::Verdict v : {qc::Verdict::kPass, qc::Verdict::kFail, qc::Verdict::kUndecided})
    if (verdict == qc::ToString(v)) u.decision.verdict = v;
  u.decision.reasons = d.at("reasons").get<std::vector<std::string>>();
  u.decision.fit_verdict = d.at("fit_verdict").get<std::string>();
  u.decision.serial = d.at("serial").get<std::string>();
  u.rig_error = j.at("rig_error").get<std::string>();
  u.out = j.at("out").get<std::vector<std::string>>();
  u.guard_band = j.at("guard_band").get<std::vector<std::string>>();
  u.named = j.at("named").get<bool>();
  u.z = j.at("z").get<std::map<std::string, double>>();
  const nlohmann::json& t = j.at("timing");
  u.decision.seconds = t.at("seconds").get<double>();
  u.cpu_seconds = t.at("cpu_seconds").get<double>();
  u.sim_seconds = t.at("sim_seconds").get<double>();
  return u;
}

}  // namespace strut::study
