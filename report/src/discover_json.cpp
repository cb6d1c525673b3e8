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

nlohmann::json NumberOrNull(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

nlohmann::json DecisiveTestJson(const ident::DecisiveTest& t) {
  return {{"models", {t.model_a, t.model_b}},
          {"static_position", t.static_position},
          {"amplitude", t.amplitude},
          {"frequency", t.frequency},
          {"periods", t.periods},
          {"sample_rate", t.sample_rate},
          {"minutes", t.minutes},
          {"separation", t.separation},
          {"separation_fixed", t.separation_fixed},
          {"separation_per_minute", t.separation_per_minute},
          {"rms_difference", RatiosJson(t.rms_difference)},
          {"channel", t.channel},
          {"candidates", t.candidates},
          {"description", t.Describe()}};
}

nlohmann::json AmbiguityJson(const ident::Ambiguity& a) {
  nlohmann::json j{{"kept", a.kept}, {"step", a.step}, {"rivals", nlohmann::json::array()}};
  for (const auto& r : a.rivals)
    j["rivals"].push_back({{"term", r.term},
                           {"model", r.model},
                           {"delta_bic", NumberOrNull(r.delta_bic)},
                           {"noise_ratio", RatiosJson(r.noise_ratio)},
                           {"at_noise_floor", r.at_noise_floor},
                           {"correlation", NumberOrNull(r.correlation)},
                           {"why", r.why}});
  j["test"] = a.test ? DecisiveTestJson(*a.test) : nlohmann::json(nullptr);
  return j;
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
                        {"removed", s.removed},
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
                                    {"qualified", c.qualified},
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
  j["ambiguities"] = nlohmann::json::array();
  for (const auto& a : r.ambiguities) j["ambiguities"].push_back(AmbiguityJson(a));
  if (r.decision) {
    const ident::Decision& d = *r.decision;
    nlohmann::json decision{{"models", nlohmann::json::array()}, {"winner", d.winner >= 0 ? nlohmann::json(d.models[d.winner]) : nlohmann::json(nullptr)},
                            {"delta_bic", NumberOrNull(d.delta_bic)}, {"margin", d.margin}, {"conclusion", d.conclusion}};
    for (std::size_t k = 0; k < d.models.size(); ++k)
      decision["models"].push_back({{"model", d.models[k]},
                                    {"converged", d.fits[k].converged},
                                    {"bic", NumberOrNull(d.fits[k].bic)},
                                    {"noise_ratio", RatiosJson(ident::PooledNoiseRatio(d.fits[k]))}});
    j["decision"] = decision;
  } else {
    j["decision"] = nullptr;
  }
  j["conclusion"] = r.conclusion;
  j["final_fit"] = report::FitToJson(r.final_fit);
  return j;
}

}  // namespace strut::report
