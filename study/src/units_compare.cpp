#include "strut/study/units_compare.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <stdexcept>

namespace strut::study {
namespace {

// A unit's "z" or "estimate" object: key -> number (null, how JSON writes a NaN, reads as NaN).
std::map<std::string, double> Numbers(const nlohmann::json& j, const std::string& where) {
  if (!j.is_object()) throw std::invalid_argument(where + " is not an object of numbers");
  std::map<std::string, double> out;
  for (const auto& [key, v] : j.items()) {
    if (v.is_null()) {
      out[key] = std::numeric_limits<double>::quiet_NaN();
    } else if (v.is_number()) {
      out[key] = v.get<double>();
    } else {
      throw std::invalid_argument(fmt::format("{}.{} is not a number", where, key));
    }
  }
  return out;
}

RunUnit ParseUnit(const nlohmann::json& j, const std::string& where) {
  if (!j.is_object() || !j.contains("seed") || !j["seed"].is_number_unsigned() || !j.contains("z"))
    throw std::invalid_argument(where + " needs a whole \"seed\" >= 0 and a \"z\" object");
  RunUnit u;
  u.seed = j["seed"].get<unsigned long>();
  u.z = Numbers(j["z"], where + ".z");
  if (j.contains("estimate")) u.estimate = Numbers(j["estimate"], where + ".estimate");
  return u;
}

// The largest relative difference of `key` so far, kept with the unit it is in.
void Widen(double a, double b, unsigned long seed, double& largest, unsigned long& at, long& count) {
  const double d = RelativeDifference(a, b);
  if (count == 0 || d > largest) {
    largest = d;
    at = seed;
  }
  ++count;
}

// One figure (z or the estimates) of one unit both runs ran: its keys into the per-parameter
// differences, a key in one run only into `missing`.
template <typename Figure>
void CompareFigure(const std::map<std::string, double>& before, const std::map<std::string, double>& now,
                   unsigned long seed, const char* what, std::map<std::string, ParameterDifference>& by_key,
                   std::vector<std::string>& missing, Figure figure) {
  for (const auto& [key, b] : before) {
    const auto n = now.find(key);
    if (n == now.end()) {
      missing.push_back(fmt::format("unit {}: {}'s {} only in the earlier run", seed, key, what));
      continue;
    }
    ParameterDifference& p = by_key[key];
    p.key = key;
    figure(p, b, n->second);
  }
  for (const auto& [key, v] : now)
    if (before.count(key) == 0) missing.push_back(fmt::format("unit {}: {}'s {} only in this run", seed, key, what));
}

}  // namespace

UnitsRun ToRun(const UnitsStudy& study) {
  UnitsRun run{"this run", {}};
  for (const UnitFit& unit : study.units) {
    RunUnit u;
    u.seed = unit.seed;
    u.z.insert(unit.z.begin(), unit.z.end());
    u.estimate.insert(unit.estimate.begin(), unit.estimate.end());
    run.units.push_back(std::move(u));
  }
  return run;
}

UnitsRun ReadUnitsRun(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::invalid_argument(fmt::format("{}: cannot be read", path));
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const nlohmann::json::parse_error& e) {
    throw std::invalid_argument(fmt::format("{}: not JSON: {}", path, e.what()));
  }
  if (!j.is_object() || !j.contains("units") || !j["units"].is_array())
    throw std::invalid_argument(fmt::format("{}: no \"units\" array: not a `strut bench units --json` file", path));
  UnitsRun run{path, {}};
  for (std::size_t i = 0; i < j["units"].size(); ++i)
    run.units.push_back(ParseUnit(j["units"][i], fmt::format("{}: units[{}]", path, i)));
  return run;
}

double RelativeDifference(double a, double b) {
  if (a == b) return 0.0;
  if (!std::isfinite(a) || !std::isfinite(b)) {
    // Two NaN are the same missing figure (a fit whose sd is undefined in both runs).
    return std::isnan(a) && std::isnan(b) ? 0.0 : std::numeric_limits<double>::infinity();
  }
  return std::abs(a - b) / std::max(std::abs(a), std::abs(b));
}

UnitsComparison CompareUnits(const UnitsRun& before, const UnitsRun& now, double tolerance) {
  UnitsComparison c;
  c.tolerance = tolerance;
  std::map<unsigned long, const RunUnit*> earlier;
  for (const RunUnit& u : before.units) {
    earlier[u.seed] = &u;
    c.before_has_estimates = c.before_has_estimates || !u.estimate.empty();
  }
  std::map<unsigned long, bool> seen;
  std::map<std::string, ParameterDifference> by_key;
  for (const RunUnit& u : now.units) {
    const auto e = earlier.find(u.seed);
    if (e == earlier.end()) {
      c.only_now.push_back(u.seed);
      continue;
    }
    seen[u.seed] = true;
    ++c.units;
    CompareFigure(e->second->z, u.z, u.seed, "z", by_key, c.missing,
                  [&](ParameterDifference& p, double b, double n) { Widen(b, n, u.seed, p.z, p.z_seed, p.units); });
    // A run written before the estimates were kept is compared by z alone.
    if (c.before_has_estimates)
      CompareFigure(e->second->estimate, u.estimate, u.seed, "estimate", by_key, c.missing,
                    [&](ParameterDifference& p, double b, double n) {
                      Widen(b, n, u.seed, p.estimate, p.estimate_seed, p.estimate_units);
                    });
  }
  for (const RunUnit& u : before.units)
    if (seen.count(u.seed) == 0) c.only_before.push_back(u.seed);
  for (auto& [key, p] : by_key) {
    c.exceeded += p.units > 0 && !(p.z <= tolerance);
    c.exceeded += p.estimate_units > 0 && !(p.estimate <= tolerance);
    c.parameters.push_back(std::move(p));
  }
  return c;
}

}  // namespace strut::study
