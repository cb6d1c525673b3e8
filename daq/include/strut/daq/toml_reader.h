#pragma once
// The one TOML reading of strut's files (the rig's channel and limits files, the simulated rig's
// truth and matrix files, the QC reference), over toml++: every error is an `Error` naming the
// file and line, and the key with its place. `where` is the place of a key: "" at the top level,
// else In("section") = "[section] ". Messages read
//   FILE:LINE:COL: TOML syntax: ...
//   FILE:LINE: [section] key: expected a number, got the string "five"
//   FILE:LINE: [section] unknown key 'k' (known: a, b)

#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <initializer_list>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>
#include <toml++/toml.h>

namespace strut::daq {

template <typename Error>
class TomlReader {
 public:
  //! `source` names the file in every message (its path, or a name for text from elsewhere).
  explicit TomlReader(std::string source) : source_(std::move(source)) {}
  const std::string& source() const { return source_; }

  //! The text of the file at `path`; `what` names it in the error ("the channel file").
  static std::string ReadFile(const std::string& path, std::string_view what) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error(fmt::format("{}: cannot open {}", path, what));
    std::ostringstream text;
    text << in.rdbuf();
    return text.str();
  }

  //! The place of the keys of a section: "[name] ", or "" for the top level.
  static std::string In(std::string_view section) {
    return section.empty() ? std::string() : fmt::format("[{}] ", section);
  }

  toml::table Parse(std::string_view text) const {
    try {
      return toml::parse(text, source_);
    } catch (const toml::parse_error& e) {
      throw Error(fmt::format("{}:{}:{}: TOML syntax: {}", source_, e.source().begin.line, e.source().begin.column,
                              e.description()));
    }
  }

  //! "FILE:LINE" of a node.
  std::string Where(const toml::node& n) const { return fmt::format("{}:{}", source_, n.source().begin.line); }
  [[noreturn]] void Fail(const toml::node& n, const std::string& what) const {
    throw Error(fmt::format("{}: {}", Where(n), what));
  }
  [[noreturn]] void Fail(const std::string& what) const { throw Error(fmt::format("{}: {}", source_, what)); }

  void RefuseUnknown(const toml::table& t, std::string_view where, std::initializer_list<const char*> keys) const {
    for (auto&& [k, v] : t) {
      if (std::find_if(keys.begin(), keys.end(), [&](const char* key) { return k.str() == key; }) == keys.end())
        UnknownKey(v, where, k.str(), fmt::format("{}", fmt::join(keys, ", ")));
    }
  }
  [[noreturn]] void UnknownKey(const toml::node& n, std::string_view where, std::string_view key,
                               std::string_view known) const {
    Fail(n, fmt::format("{}unknown key '{}' (known: {})", where, key, known));
  }

  // The value of the node of a key, or Error naming the key and what it holds instead.
  double Number(const toml::node& n, std::string_view where, std::string_view key) const {
    if (!n.is_number()) Expected(n, where, key, "a number");
    const double v = *n.value<double>();
    if (!std::isfinite(v)) Expected(n, where, key, "a finite number");
    return v;
  }
  std::int64_t Integer(const toml::node& n, std::string_view where, std::string_view key) const {
    if (!n.is_integer()) Expected(n, where, key, "an integer");
    return *n.value<std::int64_t>();
  }
  std::string Text(const toml::node& n, std::string_view where, std::string_view key) const {
    if (!n.is_string()) Expected(n, where, key, "a string");
    return *n.value<std::string>();
  }
  bool Bool(const toml::node& n, std::string_view where, std::string_view key) const {
    if (!n.is_boolean()) Expected(n, where, key, "true or false");
    return *n.value<bool>();
  }
  //! The table of a key ("[key]" in the file).
  const toml::table& Table(const toml::node& n, std::string_view where, std::string_view key) const {
    const toml::table* t = n.as_table();
    if (!t) Expected(n, where, key, fmt::format("a table ([{}])", key));
    return *t;
  }

  // The value of `key` in `t`, nullopt when the key is absent.
  std::optional<double> Number(const toml::table& t, std::string_view where, const char* key) const {
    const toml::node* n = t.get(key);
    return n ? std::optional<double>(Number(*n, where, key)) : std::nullopt;
  }
  std::optional<std::int64_t> Integer(const toml::table& t, std::string_view where, const char* key) const {
    const toml::node* n = t.get(key);
    return n ? std::optional<std::int64_t>(Integer(*n, where, key)) : std::nullopt;
  }
  std::optional<std::string> Text(const toml::table& t, std::string_view where, const char* key) const {
    const toml::node* n = t.get(key);
    return n ? std::optional<std::string>(Text(*n, where, key)) : std::nullopt;
  }
  std::optional<bool> Bool(const toml::table& t, std::string_view where, const char* key) const {
    const toml::node* n = t.get(key);
    return n ? std::optional<bool>(Bool(*n, where, key)) : std::nullopt;
  }

  //! What a node holds, in words: the string "five", the number 2.5, a table, ...
  static std::string Describe(const toml::node& n) {
    if (const auto* s = n.as_string()) return fmt::format("the string \"{}\"", s->get());
    if (const auto* i = n.as_integer()) return fmt::format("the integer {}", i->get());
    if (const auto* f = n.as_floating_point()) return fmt::format("the number {}", f->get());
    if (const auto* b = n.as_boolean()) return b->get() ? "true" : "false";
    if (n.is_table()) return "a table";
    if (n.is_array()) return "an array";
    return "a date or time";
  }

 private:
  [[noreturn]] void Expected(const toml::node& n, std::string_view where, std::string_view key,
                             std::string_view expected) const {
    Fail(n, fmt::format("{}{}: expected {}, got {}", where, key, expected, Describe(n)));
  }

  std::string source_;
};

}  // namespace strut::daq
