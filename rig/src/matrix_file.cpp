// Matrix files (test_matrix.h, docs/simulated-rig.md "Matrix files").
#include <spdlog/fmt/fmt.h>

#include <cmath>
#include <cstdint>
#include <fstream>
#include <sstream>
#include <toml++/toml.h>

#include "strut/rig/test_matrix.h"

namespace strut::rig {

MatrixPlan StandardMatrixPlan() {
  MatrixPlan plan;
  plan.experiments = StandardMatrix();
  return plan;
}

MatrixPlan ParseMatrix(std::string_view text, const std::string& source_name) {
  toml::table root;
  try {
    root = toml::parse(text, source_name);
  } catch (const toml::parse_error& e) {
    throw MatrixFileError(fmt::format("{}:{}:{}: TOML syntax: {}", source_name, e.source().begin.line,
                                      e.source().begin.column, e.description()));
  }
  const auto where = [&](const toml::node& n) { return fmt::format("{}:{}", source_name, n.source().begin.line); };
  const auto number = [&](const toml::node& n, std::string_view key) {
    if (!n.is_number()) throw MatrixFileError(fmt::format("{}: '{}' must be a number", where(n), key));
    const double v = *n.value<double>();
    if (!std::isfinite(v)) throw MatrixFileError(fmt::format("{}: '{}' must be finite", where(n), key));
    return v;
  };
  MatrixPlan plan;
  plan.source = source_name;
  for (auto&& [k, node] : root) {
    const std::string key(k.str());
    if (key == "sample_rate") {
      plan.sample_rate = number(node, key);
      if (!(*plan.sample_rate > 0)) throw MatrixFileError(fmt::format("{}: sample_rate must be positive", where(node)));
    } else if (key == "periods") {
      if (!node.is_integer()) throw MatrixFileError(fmt::format("{}: 'periods' must be an integer", where(node)));
      plan.periods = static_cast<long>(*node.value<int64_t>());
      if (*plan.periods < 1) throw MatrixFileError(fmt::format("{}: periods must be at least 1", where(node)));
    } else if (key == "experiment") {
      const toml::array* list = node.as_array();
      if (!list)
        throw MatrixFileError(fmt::format("{}: 'experiment' must be an array of tables ([[experiment]])", where(node)));
      for (const toml::node& item : *list) {
        const toml::table* t = item.as_table();
        if (!t) throw MatrixFileError(fmt::format("{}: each experiment must be a table ([[experiment]])", where(item)));
        MatrixEntry e;
        bool has_label = false, has_f = false, has_s = false, has_a = false;
        for (auto&& [ek, v] : *t) {
          const std::string name(ek.str());
          if (name == "label") {
            if (!v.is_string()) throw MatrixFileError(fmt::format("{}: 'label' must be a string", where(v)));
            e.label = *v.value<std::string>();
            has_label = true;
          } else if (name == "group") {
            if (!v.is_string()) throw MatrixFileError(fmt::format("{}: 'group' must be a string", where(v)));
            e.group = *v.value<std::string>();
          } else if (name == "frequency") {
            e.frequency = number(v, name), has_f = true;
          } else if (name == "static_position") {
            e.static_position = number(v, name), has_s = true;
          } else if (name == "amplitude") {
            e.amplitude = number(v, name), has_a = true;
          } else {
            throw MatrixFileError(fmt::format("{}: [[experiment]] unknown key '{}' (known: label, group, frequency, "
                                              "static_position, amplitude)",
                                              where(v), name));
          }
        }
        if (!has_label || !has_f || !has_s || !has_a)
          throw MatrixFileError(fmt::format("{}: [[experiment]] needs label, frequency, static_position and amplitude",
                                            where(item)));
        if (e.label.empty() || e.label.find('/') != std::string::npos)
          throw MatrixFileError(fmt::format("{}: label '{}' must be non-empty and without '/'", where(item), e.label));
        if (!(e.frequency > 0)) throw MatrixFileError(fmt::format("{}: frequency must be positive (Hz)", where(item)));
        if (e.amplitude < 0) throw MatrixFileError(fmt::format("{}: amplitude must not be negative (m)", where(item)));
        for (const auto& other : plan.experiments)
          if (other.label == e.label)
            throw MatrixFileError(fmt::format("{}: label '{}' appears twice", where(item), e.label));
        plan.experiments.push_back(e);
      }
    } else {
      throw MatrixFileError(
          fmt::format("{}: unknown key '{}' (known: sample_rate, periods, [[experiment]])", where(node), key));
    }
  }
  if (plan.experiments.empty()) throw MatrixFileError(fmt::format("{}: the matrix has no [[experiment]]", source_name));
  return plan;
}

std::string ReadMatrixText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw MatrixFileError(fmt::format("{}: cannot open the matrix file", path));
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

MatrixPlan ReadMatrixFile(const std::string& path) { return ParseMatrix(ReadMatrixText(path), path); }

}  // namespace strut::rig
