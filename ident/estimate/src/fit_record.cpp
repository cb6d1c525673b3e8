#include "strut/ident/fit_record.h"

#include <fmt/format.h>
#include <fstream>
#include <stdexcept>

namespace strut::ident {

FitRecord ParseFitJson(const nlohmann::json& j, const std::string& source, Causality causality) {
  const auto fail = [&](const std::string& what) { return std::invalid_argument(fmt::format("fit {}: {}", source, what)); };
  if (!j.is_object()) throw fail("not a fit's JSON object (strut identify --json writes one)");
  if (!j.contains("model") || !j["model"].is_string()) throw fail("no 'model' (the fitted composition)");
  if (!j.contains("parameters") || !j["parameters"].is_array()) throw fail("no 'parameters' array");
  FitRecord r;
  r.source = source;
  try {
    r.model = Model::Build(j["model"].get<std::string>(), causality);
  } catch (const ModelError& e) {
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
