#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <fstream>
#include <map>

#include "strut/ident/fit_report.h"

namespace strut::ident {
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
                               {"sd", Number(fit.sd[i])},
                               {"sd_input_noise_factor",
                                Number(static_cast<std::size_t>(i) < fit.input_noise_sd_factor.size()
                                           ? fit.input_noise_sd_factor[i]
                                           : NAN)},
                               {"sd_misfit_factor",
                                Number(static_cast<std::size_t>(i) < fit.misfit_sd_factor.size() ? fit.misfit_sd_factor[i]
                                                                                                 : NAN)},
                               {"sd_calibration",
                                Number(static_cast<std::size_t>(i) < fit.calibration_sd.size() ? fit.calibration_sd[i] : NAN)},
                               {"estimated", static_cast<bool>(fit.estimated[i])}});
  }
  j["calibration"] = nlohmann::json::object();  // the transducer gains' relative sd the intervals hold
  for (const auto& [channel, sd] : fit.calibration) j["calibration"][channel] = sd;
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

FitRecord ParseFitJson(const nlohmann::json& j, const std::string& source, Causality causality) {
  const auto fail = [&](const std::string& what) { return std::invalid_argument(fmt::format("fit {}: {}", source, what)); };
  if (!j.is_object()) throw fail("not a fit's JSON object (strut identify --json writes one)");
  if (!j.contains("model") || !j["model"].is_string()) throw fail("no 'model' (the fitted composition)");
  if (!j.contains("parameters") || !j["parameters"].is_array()) throw fail("no 'parameters' array");
  FitRecord r;
  r.source = source;
  try {
    r.model = Model::Build(j["model"].get<std::string>(), causality);
  } catch (const std::exception& e) {
    throw fail(fmt::format("model '{}': {}", j["model"].get<std::string>(), e.what()));
  }
  r.parameters = r.model.defaults();
  r.converged = j.value("converged", false);
  r.verdict = j.value("verdict", std::string());
  std::map<int, double> sd;  // position: posterior sd (NaN when the file has none)
  for (std::size_t k = 0; k < j["parameters"].size(); ++k) {
    const nlohmann::json& p = j["parameters"][k];
    const std::string key = p.is_object() && p.contains("index") && p["index"].is_string() ? p["index"].get<std::string>() : "";
    if (key.empty()) throw fail(fmt::format("parameters[{}] has no 'index' (theta...)", k));
    const auto position = r.parameters.find(key);
    if (!position) throw fail(fmt::format("parameter {} is not one of model '{}'", key, r.model.composition()));
    if (!p.contains("value") || !p["value"].is_number() || !std::isfinite(p["value"].get<double>()))
      throw fail(fmt::format("parameter {} has no finite value", key));
    r.parameters.values()[*position] = p["value"].get<double>();
    if (p.value("estimated", false)) {
      r.estimated_positions.push_back(*position);
      sd[*position] = p.contains("sd") && p["sd"].is_number() ? p["sd"].get<double>() : NAN;
    }
  }
  const int ne = static_cast<int>(r.estimated_positions.size());
  // Correlation in the file's order of names; covariance in estimated_positions' order.
  Eigen::MatrixXd correlation = Eigen::MatrixXd::Identity(ne, ne);
  if (j.contains("correlation") && j["correlation"].is_object() && ne > 0) {
    const nlohmann::json& names = j["correlation"].value("parameters", nlohmann::json::array());
    const nlohmann::json& rows = j["correlation"].value("matrix", nlohmann::json::array());
    if (names.size() != static_cast<std::size_t>(ne) || rows.size() != names.size())
      throw fail(fmt::format("the correlation matrix names {} parameters with {} rows, the fit estimates {}",
                             names.size(), rows.size(), ne));
    std::vector<int> order(ne);  // file row a -> our index
    for (int a = 0; a < ne; ++a) {
      const auto position = names[a].is_string() ? r.parameters.find(names[a].get<std::string>()) : std::nullopt;
      const auto it = position ? std::find(r.estimated_positions.begin(), r.estimated_positions.end(), *position)
                               : r.estimated_positions.end();
      if (it == r.estimated_positions.end())
        throw fail(fmt::format("correlation parameter {} is not an estimated parameter", names[a].dump()));
      order[a] = static_cast<int>(it - r.estimated_positions.begin());
    }
    for (int a = 0; a < ne; ++a) {
      if (!rows[a].is_array() || rows[a].size() != static_cast<std::size_t>(ne))
        throw fail(fmt::format("correlation row {} does not have {} values", a, ne));
      for (int b = 0; b < ne; ++b)
        correlation(order[a], order[b]) = rows[a][b].is_number() ? rows[a][b].get<double>() : NAN;
    }
  }
  r.covariance.resize(ne, ne);
  for (int a = 0; a < ne; ++a)
    for (int b = 0; b < ne; ++b)
      r.covariance(a, b) = sd[r.estimated_positions[a]] * sd[r.estimated_positions[b]] * correlation(a, b);
  return r;
}

FitRecord ReadFitJson(const std::string& path, Causality causality) {
  std::ifstream in(path);
  if (!in) throw std::invalid_argument(fmt::format("fit {}: cannot be read", path));
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw std::invalid_argument(fmt::format("fit {}: not JSON: {}", path, e.what()));
  }
  return ParseFitJson(j, path, causality);
}

}  // namespace strut::ident
