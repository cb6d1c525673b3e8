// Matrix files (test_matrix.h, docs/simulated-rig.md "Matrix files").
#include <spdlog/fmt/fmt.h>

#include <cmath>
#include <cstdint>
#include <string_view>

#include "strut/daq/toml_reader.h"
#include "strut/rig/test_matrix.h"

namespace strut::rig {

MatrixPlan StandardMatrixPlan() {
  MatrixPlan plan;
  plan.experiments = StandardMatrix();
  return plan;
}

std::string MatrixFileText(const MatrixPlan& plan, const std::string& comment) {
  std::string s;
  for (std::size_t start = 0; !comment.empty() && start <= comment.size();) {
    const auto end = comment.find('\n', start);
    s += "# " + comment.substr(start, end == std::string::npos ? std::string::npos : end - start) + "\n";
    if (end == std::string::npos) break;
    start = end + 1;
  }
  if (plan.sample_rate) s += fmt::format("sample_rate = {}\n", *plan.sample_rate);
  if (plan.periods) s += fmt::format("periods = {}\n", *plan.periods);
  for (const MatrixEntry& e : plan.experiments) {
    s += fmt::format("\n[[experiment]]\nlabel = \"{}\"\n", e.label);
    if (!e.group.empty()) s += fmt::format("group = \"{}\"\n", e.group);
    s += fmt::format("frequency = {}\nstatic_position = {}\namplitude = {}\n", e.frequency, e.static_position,
                     e.amplitude);
  }
  return s;
}

MatrixPlan ParseMatrix(std::string_view text, const std::string& source_name) {
  const daq::TomlReader<MatrixFileError> toml(source_name);
  const toml::table root = toml.Parse(text);
  const auto where = [&](const toml::node& n) { return toml.Where(n); };
  MatrixPlan plan;
  plan.source = source_name;
  for (auto&& [k, node] : root) {
    const std::string key(k.str());
    if (key == "sample_rate") {
      plan.sample_rate = toml.Number(node, "", key);
      if (!(*plan.sample_rate > 0)) throw MatrixFileError(fmt::format("{}: sample_rate must be positive", where(node)));
    } else if (key == "periods") {
      plan.periods = static_cast<long>(toml.Integer(node, "", key));
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
          constexpr std::string_view in = "[[experiment]] ";
          if (name == "label") {
            e.label = toml.Text(v, in, name);
            has_label = true;
          } else if (name == "group") {
            e.group = toml.Text(v, in, name);
          } else if (name == "frequency") {
            e.frequency = toml.Number(v, in, name), has_f = true;
          } else if (name == "static_position") {
            e.static_position = toml.Number(v, in, name), has_s = true;
          } else if (name == "amplitude") {
            e.amplitude = toml.Number(v, in, name), has_a = true;
          } else {
            toml.UnknownKey(v, in, name, "label, group, frequency, static_position, amplitude");
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
      toml.UnknownKey(node, "", key, "sample_rate, periods, [[experiment]]");
    }
  }
  if (plan.experiments.empty()) throw MatrixFileError(fmt::format("{}: the matrix has no [[experiment]]", source_name));
  return plan;
}

std::string ReadMatrixText(const std::string& path) {
  return daq::TomlReader<MatrixFileError>::ReadFile(path, "the matrix file");
}

MatrixPlan ReadMatrixFile(const std::string& path) { return ParseMatrix(ReadMatrixText(path), path); }

}  // namespace strut::rig
