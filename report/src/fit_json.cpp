#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <fstream>
#include <map>

#include "strut/report/fit_report.h"

namespace strut::report {

using namespace strut::ident;

using namespace strut::report;
namespace {

nlohmann::json Number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

nlohmann::json ChannelJson(const ChannelStatistics& c) {
  return {{"mean", Number(c.mean)},
          {"sd", Number(c.sd)},
          {"rms", Number(c.rms)},
          {"noise_ratio", Number(c.noise_ratio)},
          {"fitted", c.fitted}};
}

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
                               {"sd", Number(fit.estimates[i].sd)},
                               {"sd_input_noise_factor", Number(fit.estimates[i].input_noise_sd_factor)},
                               {"sd_misfit_factor", Number(fit.estimates[i].misfit_sd_factor)},
                               {"sd_calibration", Number(fit.estimates[i].calibration_sd)},
                               {"estimated", static_cast<bool>(fit.estimates[i].estimated)}});
  }
  j["calibration"] = nlohmann::json::object();  // the transducer gains' relative sd the intervals hold
  for (const auto& [channel, sd] : fit.calibration) j["calibration"][channel] = sd;
  j["channels"] = nlohmann::json::array();
  for (const FitChannel& c : fit.channels)
    j["channels"].push_back({{"name", c.name},
                             {"variance", Number(c.variance)},
                             {"noise_floor_variance", Number(c.noise_floor_variance)},
                             {"rms", Number(c.rms)},
                             {"noise_ratio", Number(c.noise_ratio)},
                             {"noise_ratio_sd", Number(c.noise_ratio_sd)},
                             {"noise_floor_limit", Number(c.noise_floor_limit)},
                             {"above_noise_floor", c.AboveNoiseFloor()}});
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
    for (const ChannelStatistics& c : e.channels) x[c.channel] = ChannelJson(c);
    j["experiments"].push_back(x);
  }
  j["transient_experiments"] = nlohmann::json::array();
  for (const TransientExperimentFit& t : fit.transient_experiments) {
    nlohmann::json x{{"label", t.label},
                     {"kind", t.kind},
                     {"session", t.session},
                     {"drop_mass", t.drop_mass},
                     {"impact_velocity", t.impact_velocity},
                     {"samples", t.time.size()},
                     {"converged", t.converged}};
    if (!t.error.empty()) x["error"] = t.error;
    for (const ChannelStatistics& c : t.channels) {
      x[c.channel] = ChannelJson(c);
      x[c.channel]["noise_variance"] =
          Number(t.noise_variance.count(c.channel) ? t.noise_variance.at(c.channel) : NAN);
    }
    j["transient_experiments"].push_back(x);
  }
  // What each experiment adds: per estimated parameter its share of the information and the sd
  // without it (null: undetermined without it).
  j["contributions"] = nlohmann::json::array();
  for (const ExperimentContribution& c : fit.contributions) {
    nlohmann::json share = nlohmann::json::object(), without = nlohmann::json::object();
    for (int i : fit.estimated_positions) {
      const std::string key = fit.parameters.spec(i).key();
      share[key] = Number(c.information_share[i]);
      without[key] = Number(c.sd_without[i]);
    }
    j["contributions"].push_back(
        {{"label", c.label}, {"kind", c.kind}, {"information_share", share}, {"sd_without", without}});
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

}  // namespace strut::report
