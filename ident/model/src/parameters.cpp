#include "strut/ident/parameters.h"

#include "strut/ident/assignments.h"

#include <cerrno>
#include <charconv>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

#include <fmt/format.h>

namespace strut::ident {
namespace {

std::string_view Trim(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  return s;
}


// "theta4 gas_area = -1 m^2 is outside its physical range (0, inf)".
std::string OutOfRange(const ParameterSpec& spec, double value) {
  return fmt::format("{} {} = {:g}{}{} is outside its physical range {}", spec.key(), spec.name, value,
                     spec.unit.empty() || spec.unit == "-" ? "" : " ", spec.unit == "-" ? "" : spec.unit,
                     spec.range.ToString());
}

std::string Bound(double v) {
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  return fmt::format("{:g}", v);
}

}  // namespace

std::string PhysicalRange::ToString() const {
  return fmt::format("{}{}, {}{}", lower_open || std::isinf(lower) ? "(" : "[", Bound(lower), Bound(upper),
                     upper_open || std::isinf(upper) ? ")" : "]");
}

ParameterSet::ParameterSet(std::vector<ParameterSpec> specs) : specs_(std::move(specs)) {
  values_.reserve(specs_.size());
  for (const auto& s : specs_) values_.push_back(s.default_value);
}

std::optional<int> ParameterSet::find(std::string_view key) const {
  key = Trim(key);
  std::string_view digits = key;
  if (digits.rfind("theta", 0) == 0) digits.remove_prefix(5);
  int index = 0;
  const auto [ptr, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), index);
  const bool numeric = !digits.empty() && ec == std::errc() && ptr == digits.data() + digits.size();
  for (int i = 0; i < size(); ++i) {
    if (numeric ? specs_[i].index == index : specs_[i].name == key) return i;
  }
  return std::nullopt;
}

int ParameterSet::position(std::string_view key) const {
  if (auto p = find(key)) return *p;
  std::string known;
  for (const auto& s : specs_) known += fmt::format(" {}({})", s.key(), s.name);
  throw ParameterError(fmt::format("unknown parameter '{}'; this model has:{}", key, known));
}

int ParameterSet::position_of_index(int index) const {
  for (int i = 0; i < size(); ++i)
    if (specs_[i].index == index) return i;
  return -1;
}

std::optional<std::string> ParameterSet::RangeViolation() const {
  for (int i = 0; i < size(); ++i)
    if (!specs_[i].range.contains(values_[i])) return OutOfRange(specs_[i], values_[i]);
  return std::nullopt;
}

void ParameterSet::Validate() const {
  if (auto violation = RangeViolation()) throw ParameterError(*violation);
}

std::optional<double> ParseNumber(std::string_view text) {
  text = Trim(text);
  if (text.empty()) return std::nullopt;
  const std::string copy(text);
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(copy.c_str(), &end);
  if (end != copy.c_str() + copy.size() || errno == ERANGE || !std::isfinite(v)) return std::nullopt;
  return v;
}

std::vector<Assignment> SplitAssignments(std::string_view text, std::string_view option, std::string_view form) {
  std::vector<Assignment> out;
  if (Trim(text).empty()) return out;
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = text.find(',', start);
    const std::string_view item = Trim(text.substr(start, comma == std::string_view::npos ? comma : comma - start));
    if (item.empty())
      throw ParameterError(fmt::format("{}: '{}' has an empty item (two commas, or one at an end)", option, text));
    const std::size_t eq = item.find('=');
    const std::string_view name = eq == std::string_view::npos ? std::string_view() : Trim(item.substr(0, eq));
    if (name.empty()) throw ParameterError(fmt::format("{}: '{}' is not {}", option, item, form));
    out.push_back({item, name, Trim(item.substr(eq + 1))});
    if (comma == std::string_view::npos) return out;
    start = comma + 1;
  }
}

void ParameterSet::apply_assignments(std::string_view assignments) {
  std::vector<double> updated = values_;
  for (const Assignment& a : SplitAssignments(assignments, "--set", "NAME=VALUE")) {
    const auto value = ParseNumber(a.value);
    if (!value) throw ParameterError(fmt::format("--set: '{}': '{}' is not a finite number", a.item, a.value));
    const int p = position(a.name);
    if (!specs_[p].range.contains(*value))
      throw ParameterError(fmt::format("--set: '{}': {}", a.item, OutOfRange(specs_[p], *value)));
    updated[p] = *value;
  }
  values_ = std::move(updated);
}

std::vector<ParameterFileEntry> ReadParameterFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw ParameterError(fmt::format("{}: cannot open parameter file", path));
  std::vector<ParameterFileEntry> entries;
  std::set<std::string> seen;
  std::string raw;
  int line_number = 0;
  while (std::getline(in, raw)) {
    ++line_number;
    std::string_view line = raw;
    if (const auto hash = line.find('#'); hash != std::string_view::npos) line = line.substr(0, hash);
    line = Trim(line);
    if (line.empty()) continue;
    const auto where = [&] { return fmt::format("{}:{}", path, line_number); };
    const std::size_t eq = line.find('=');
    if (eq == std::string_view::npos)
      throw ParameterError(fmt::format("{}: expected 'NAME = VALUE', got '{}'", where(), line));
    ParameterFileEntry e;
    e.line = line_number;
    e.name = std::string(Trim(line.substr(0, eq)));
    if (e.name.empty()) throw ParameterError(fmt::format("{}: missing parameter name", where()));
    if (!seen.insert(e.name).second)
      throw ParameterError(fmt::format("{}: parameter '{}' given twice", where(), e.name));
    std::istringstream rest{std::string(line.substr(eq + 1))};
    std::string word;
    bool have_value = false;
    while (rest >> word) {
      if (!have_value) {
        const auto v = ParseNumber(word);
        if (!v) throw ParameterError(fmt::format("{}: '{}' is not a finite number", where(), word));
        e.value = *v;
        have_value = true;
      } else if (word == "estimate") {
        e.estimate = true;
      } else if (word == "fixed") {
        e.estimate = false;
      } else if (word.rfind("sd=", 0) == 0) {
        const auto v = ParseNumber(std::string_view(word).substr(3));
        if (!v || *v <= 0) throw ParameterError(fmt::format("{}: '{}' needs a positive number", where(), word));
        e.prior_sd = *v;
      } else {
        throw ParameterError(fmt::format("{}: unknown word '{}' (expected estimate, fixed or sd=VALUE)", where(), word));
      }
    }
    if (!have_value) throw ParameterError(fmt::format("{}: missing value for '{}'", where(), e.name));
    entries.push_back(std::move(e));
  }
  return entries;
}

void ParameterSet::apply_file(const std::string& path) {
  std::vector<double> updated = values_;  // all or nothing
  for (const auto& e : ReadParameterFile(path)) {
    const auto p = find(e.name);
    if (!p)
      throw ParameterError(fmt::format("{}:{}: this model has no parameter '{}'", path, e.line, e.name));
    if (!specs_[*p].range.contains(e.value))
      throw ParameterError(fmt::format("{}:{}: {}", path, e.line, OutOfRange(specs_[*p], e.value)));
    updated[*p] = e.value;
  }
  values_ = std::move(updated);
}

std::string ParameterSet::table() const {
  std::string out;
  for (int i = 0; i < size(); ++i)
    out += fmt::format("  {:<8} {:<28} {:>13.6g} {}\n", specs_[i].key(), specs_[i].name, values_[i], specs_[i].unit);
  return out;
}

}  // namespace strut::ident
