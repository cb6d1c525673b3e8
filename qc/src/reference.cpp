#include "strut/qc/reference.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "strut/daq/toml_reader.h"
#include "strut/ident/model.h"
#include "strut/qc/quantities.h"

namespace strut::qc {
namespace {

bool Known(std::string_view name) {
  const auto& names = QuantityNames();
  return std::find(names.begin(), names.end(), name) != names.end();
}

std::string KnownList() {
  std::string list;
  for (const auto& n : QuantityNames()) list += (list.empty() ? "" : ", ") + n;
  return list;
}

//! A band from its parts: `tolerance` (relative, symmetric) or `lower` and `upper`.
Band MakeBand(const std::string& where, const std::string& name, std::optional<double> nominal,
              std::optional<double> lower, std::optional<double> upper, std::optional<double> tolerance) {
  if (!nominal) throw ReferenceError(where + ": '" + name + "' needs a nominal value");
  if (tolerance && (lower || upper))
    throw ReferenceError(where + ": '" + name + "' gives both tolerance and lower/upper; give one");
  Band b{name, *nominal, 0.0, 0.0};
  if (tolerance) {
    if (!(*tolerance > 0 && *tolerance < 1))
      throw ReferenceError(fmt::format("{}: '{}': tolerance {} must be a fraction in (0, 1)", where, name, *tolerance));
    b.lower = *nominal - *tolerance * std::abs(*nominal);
    b.upper = *nominal + *tolerance * std::abs(*nominal);
  } else {
    if (!lower || !upper) throw ReferenceError(where + ": '" + name + "' needs lower and upper (or tolerance)");
    b.lower = *lower;
    b.upper = *upper;
  }
  if (!(std::isfinite(b.nominal) && std::isfinite(b.lower) && std::isfinite(b.upper)))
    throw ReferenceError(where + ": '" + name + "' has a value that is not a finite number");
  if (!(b.lower <= b.nominal && b.nominal <= b.upper && b.lower < b.upper))
    throw ReferenceError(fmt::format("{}: '{}': the band needs lower <= nominal <= upper and lower < upper (got {}, {}, {})",
                                     where, name, b.lower, b.nominal, b.upper));
  return b;
}

using TomlReader = daq::TomlReader<ReferenceError>;

Reference ParseToml(std::string_view text, const std::string& source) {
  const TomlReader toml(source);
  const toml::table root = toml.Parse(text);
  Reference r{source, "nominal-file", "", {}};
  for (const auto& [key, node] : root) {
    const std::string where = toml.Where(node);
    const std::string name(key.str());
    if (name == "model") {
      r.model = toml.Text(node, "", name);
      continue;
    }
    if (!Known(name)) throw ReferenceError(where + ": unknown quantity '" + name + "' (known: " + KnownList() + ")");
    const toml::table& t = toml.Table(node, "", name);
    const std::string in = TomlReader::In(name);
    toml.RefuseUnknown(t, in, {"nominal", "lower", "upper", "tolerance"});
    r.bands.push_back(MakeBand(where, name, toml.Number(t, in, "nominal"), toml.Number(t, in, "lower"),
                               toml.Number(t, in, "upper"), toml.Number(t, in, "tolerance")));
  }
  return r;
}

std::optional<double> OptionalNumber(const nlohmann::json& j, const std::string& key, const std::string& where) {
  if (!j.contains(key)) return std::nullopt;
  if (!j[key].is_number()) throw ReferenceError(where + "." + key + " must be a number");
  return j[key].get<double>();
}

nlohmann::json ParseJson(std::string_view text, const std::string& source) {
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::parse_error& e) {
    throw ReferenceError(source + ": not valid JSON: " + e.what());
  }
}

Reference ParseJsonNominal(const nlohmann::json& j, const std::string& source) {
  Reference r{source, "nominal-file", "", {}};
  if (!j.is_object() || !j.contains("quantities") || !j["quantities"].is_object())
    throw ReferenceError(source + ": a JSON reference needs an object \"quantities\" (or is an identify JSON with "
                                  "\"model\" and \"parameters\")");
  if (j.contains("model")) {
    if (!j["model"].is_string()) throw ReferenceError(source + ": \"model\" must be a string");
    r.model = j["model"].get<std::string>();
  }
  for (const auto& [name, q] : j["quantities"].items()) {
    const std::string where = source + ": quantities." + name;
    if (!Known(name)) throw ReferenceError(where + ": unknown quantity (known: " + KnownList() + ")");
    if (!q.is_object()) throw ReferenceError(where + " must be an object");
    for (const auto& [k, v] : q.items())
      if (k != "nominal" && k != "lower" && k != "upper" && k != "tolerance")
        throw ReferenceError(where + ": unknown key '" + k + "' (nominal, lower, upper, tolerance)");
    r.bands.push_back(MakeBand(where, name, OptionalNumber(q, "nominal", where), OptionalNumber(q, "lower", where),
                               OptionalNumber(q, "upper", where), OptionalNumber(q, "tolerance", where)));
  }
  return r;
}

}  // namespace

const std::vector<DefaultBand>& DefaultBands() {
  static const std::vector<DefaultBand> bands = {
      {"charge_pressure", true, 0.05, 0.05},       // a charging station holds +-2 %; 5 % is a defect
      {"gas_column", true, 0.03, 0.03},            // 3 % of 0.30 m is 45 mL of oil in the nominal unit
      {"friction", true, 0.4, 0.6},                // seals scatter; twice nominal is worn or dry
      {"orifice_damping", true, 0.3, 0.4},         // Cd scatter of a machined orifice
      {"viscous_damping", true, 1.0, 2.0},         // absent to three times: above is a leak
      {"wall_heat_conductance", true, 0.3, 0.4},   // oil mist and wall wetting vary
      {"load_cell_zero", false, 300.0, 300.0},     // the rig's load cell zero, +-300 N
  };
  return bands;
}

const Band* Reference::find(std::string_view name) const {
  for (const Band& b : bands)
    if (b.name == name) return &b;
  return nullptr;
}

Reference ReferenceFromFitJson(const std::string& json_text, const std::string& source) {
  const nlohmann::json j = ParseJson(json_text, source);
  if (!j.contains("model") || !j["model"].is_string() || !j.contains("parameters") || !j["parameters"].is_array())
    throw ReferenceError(source + ": not an identify JSON (needs \"model\" and \"parameters\")");
  // A golden unit's values are trusted only from a fit that explains its data.
  if (j.contains("verdict") && j["verdict"] != "at-noise-floor")
    throw ReferenceError(source + ": the golden unit's fit is " + j["verdict"].dump() +
                         "; a reference needs a fit at the noise floor");
  Reference r{source, "golden-fit", j["model"].get<std::string>(), {}};
  ident::Model model = [&] {
    try {
      return ident::Model::Build(r.model, ident::Causality::kStrokeInput);
    } catch (const ident::ModelError& e) {
      throw ReferenceError(source + ": model '" + r.model + "': " + e.what());
    }
  }();
  std::vector<double> theta = model.defaults().values();
  for (const auto& p : j["parameters"]) {
    if (!p.contains("index") || !p["index"].is_string() || !p.contains("value") || !p["value"].is_number())
      throw ReferenceError(source + ": a parameter without \"index\" or a numeric \"value\": " + p.dump());
    const std::string key = p["index"].get<std::string>();
    const auto at = model.defaults().find(key);
    if (!at) throw ReferenceError(source + ": parameter " + key + " is not in the model " + r.model);
    theta[*at] = p["value"].get<double>();
  }
  std::vector<Quantity> values;
  try {
    values = ComputeQuantities(model, theta);
  } catch (const std::invalid_argument& e) {  // a parameter a quantity needs is not in the model
    throw ReferenceError(source + ": the golden unit's quantities cannot be computed: " + e.what());
  }
  for (const Quantity& q : values) {
    for (const DefaultBand& d : DefaultBands()) {
      if (d.name != q.name) continue;
      Band b{q.name, q.value, 0.0, 0.0};
      if (d.relative) {
        b.lower = q.value - d.below * std::abs(q.value);
        b.upper = q.value + d.above * std::abs(q.value);
      } else {
        b.lower = q.value - d.below;
        b.upper = q.value + d.above;
      }
      r.bands.push_back(b);
    }
  }
  return r;
}

Reference ParseNominalFile(std::string_view text, const std::string& source) {
  const auto first = text.find_first_not_of(" \t\r\n");
  if (first != std::string_view::npos && text[first] == '{') return ParseJsonNominal(ParseJson(text, source), source);
  return ParseToml(text, source);
}

Reference ReadReference(const std::string& path) {
  const std::string text = TomlReader::ReadFile(path, "the reference file");
  const auto first = text.find_first_not_of(" \t\r\n");
  if (first != std::string::npos && text[first] == '{') {
    const nlohmann::json j = ParseJson(text, path);
    if (j.contains("parameters") && j.contains("model")) return ReferenceFromFitJson(text, path);
    return ParseJsonNominal(j, path);
  }
  return ParseToml(text, path);
}

}  // namespace strut::qc
