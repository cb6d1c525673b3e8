#include <cmath>

#include "strut/ident/fit_report.h"

namespace strut::ident {
namespace {

nlohmann::json Number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

}  // namespace

nlohmann::json FitToJson(const FitSummary& fit) {
  nlohmann::json j;
  j["model"] = fit.model;
  j["converged"] = fit.converged;
  j["verdict"] = ToString(fit.Verdict());
  j["verdict_text"] = fit.VerdictText();
  j["iterations"] = fit.iterations;
  j["parameters"] = nlohmann::json::array();
  for (int i = 0; i < fit.parameters.size(); ++i) {
    const ParameterSpec& s = fit.parameters.spec(i);
    j["parameters"].push_back({{"index", s.key()},
                               {"name", s.name},
                               {"unit", s.unit},
                               {"value", Number(fit.parameters.value(i))},
                               {"sd", Number(fit.sd[i])},
                               {"sd_input_noise_factor",
                                Number(static_cast<std::size_t>(i) < fit.input_noise_sd_factor.size()
                                           ? fit.input_noise_sd_factor[i]
                                           : NAN)},
                               {"sd_misfit_factor",
                                Number(static_cast<std::size_t>(i) < fit.misfit_sd_factor.size() ? fit.misfit_sd_factor[i]
                                                                                                 : NAN)},
                               {"estimated", static_cast<bool>(fit.estimated[i])}});
  }
  j["channels"] = nlohmann::json::array();
  for (const FitChannel& c : fit.channels)
    j["channels"].push_back({{"name", c.name},
                             {"variance", Number(c.variance)},
                             {"noise_floor_variance", Number(c.noise_floor_variance)},
                             {"rms", Number(c.rms)},
                             {"noise_ratio", Number(c.noise_ratio)}});
  j["experiments"] = nlohmann::json::array();
  for (const ExperimentFit& e : fit.experiments) {
    nlohmann::json x{{"label", e.label},
                     {"group", e.group},
                     {"session", e.session},
                     {"frequency", e.frequency},
                     {"amplitude", e.amplitude},
                     {"static_position", e.static_position},
                     {"converged", e.converged}};
    if (!e.error.empty()) x["error"] = e.error;
    for (const ChannelStatistics& c : e.channels)
      x[c.channel] = {{"mean", Number(c.mean)},
                      {"sd", Number(c.sd)},
                      {"rms", Number(c.rms)},
                      {"noise_ratio", Number(c.noise_ratio)},
                      {"fitted", c.fitted}};
    j["experiments"].push_back(x);
  }
  j["loglik"] = Number(fit.loglik);
  j["aic"] = Number(fit.aic);
  j["bic"] = Number(fit.bic);
  j["observations"] = fit.observations;
  j["warnings"] = fit.warnings;
  nlohmann::json names = nlohmann::json::array();
  for (int i : fit.estimated_positions) names.push_back(fit.parameters.spec(i).key());
  nlohmann::json rows = nlohmann::json::array();
  for (Eigen::Index a = 0; a < fit.correlation.rows(); ++a) {
    nlohmann::json row = nlohmann::json::array();
    for (Eigen::Index b = 0; b < fit.correlation.cols(); ++b) row.push_back(Number(fit.correlation(a, b)));
    rows.push_back(row);
  }
  j["correlation"] = {{"parameters", names}, {"matrix", rows}};
  j["history"] = nlohmann::json::array();
  for (const FitIteration& h : fit.history)
    j["history"].push_back({{"iteration", h.iteration}, {"loglik", Number(h.objective)}, {"step", h.step}});
  return j;
}

}  // namespace strut::ident
