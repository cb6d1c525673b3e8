// The discovery's JSON record (discover_report.h).
#include <cmath>
#include <map>
#include <string>

#include "strut/report/discover_report.h"
#include "strut/report/fit_report.h"

namespace strut::report {
namespace {

nlohmann::json RatiosJson(const std::map<std::string, double>& ratio) {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& [c, r] : ratio) j[c] = std::isfinite(r) ? nlohmann::json(r) : nlohmann::json(nullptr);
  return j;
}

nlohmann::json FindingJson(const ident::Finding& f) {
  return {{"locus", f.locus}, {"channel", f.channel}, {"score", f.score}, {"detail", f.detail}};
}

}  // namespace

nlohmann::json DiscoveryJson(const ident::DiscoveryResult& r) {
  nlohmann::json j;
  j["baseline"] = {{"model", r.baseline.model},
                   {"loglik", r.baseline.loglik},
                   {"bic", r.baseline.bic},
                   {"noise_ratio", RatiosJson(ident::PooledNoiseRatio(r.baseline))},
                   {"verdict", ident::ToString(r.baseline.Verdict())}};
  j["nothing_missing"] = r.nothing_missing;
  j["mismatch"] = nlohmann::json::array();
  for (const auto& f : r.mismatch) j["mismatch"].push_back(FindingJson(f));
  j["missing"] = r.missing;
  j["final_model"] = r.final_model;
  j["steps"] = nlohmann::json::array();
  for (const auto& s : r.steps) {
    nlohmann::json step{{"term", s.term},
                        {"empirical", s.empirical},
                        {"evidence", s.evidence},
                        {"delta_bic", s.delta_bic},
                        {"noise_before", RatiosJson(s.noise_before)},
                        {"noise_after", RatiosJson(s.noise_after)},
                        {"cv_noise_ratio_before", s.cv_before},
                        {"cv_noise_ratio_after", s.cv_after},
                        {"parameters", nlohmann::json::object()},
                        {"candidates", nlohmann::json::array()}};
    for (const auto& [key, value] : s.parameters) step["parameters"][key] = value;
    for (const auto& c : s.candidates)
      step["candidates"].push_back({{"term", c.term},
                                    {"ok", c.ok},
                                    {"delta_bic", c.delta_bic},
                                    {"evidence", c.evidence},
                                    {"noise_ratio", RatiosJson(c.noise_ratio)},
                                    {"cv_noise_ratio", std::isfinite(c.cv_ratio) ? nlohmann::json(c.cv_ratio) : nlohmann::json(nullptr)},
                                    {"verdict", c.verdict},
                                    {"error", c.error}});
    j["steps"].push_back(step);
  }
  j["unexplained"] = nlohmann::json::array();
  for (const auto& f : r.unexplained) j["unexplained"].push_back(FindingJson(f));
  if (r.discrepancy && !r.discrepancy->functions.empty()) {
    const ident::EmpiricalDiscrepancy& d = *r.discrepancy;
    nlohmann::json e{{"empirical", true}, {"functions", nlohmann::json::array()}, {"dependence", d.dependence},
                     {"resembles", d.resembles}, {"curves", nlohmann::json::array()}};
    for (const auto& f : d.functions)
      e["functions"].push_back({{"parameter", "theta" + std::to_string(f.index)},
                                {"name", f.name},
                                {"shape", f.shape},
                                {"resembles", f.resembles},
                                {"value", f.value},
                                {"sd", std::isfinite(f.sd) ? nlohmann::json(f.sd) : nlohmann::json(nullptr)}});
    for (const auto& c : d.curves) e["curves"].push_back({{"label", c.label}, {"x", c.x}, {"force", c.force}});
    j["discrepancy"] = e;
  } else {
    j["discrepancy"] = nullptr;
  }
  j["conclusion"] = r.conclusion;
  j["final_fit"] = report::FitToJson(r.final_fit);
  return j;
}

}  // namespace strut::report
