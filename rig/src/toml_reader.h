#pragma once
// The TOML reading the rig's files share (the channel file, the limits file): every error is an
// `Error` naming the file and line, and the key with its place (`where`: "" or "[section] ").

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

namespace strut::rig {

template <typename Error>
class TomlReader {
 public:
  explicit TomlReader(std::string source) : source_(std::move(source)) {}

  //! The text of the file at `path`; `what` names it in the error ("the channel file").
  static std::string ReadFile(const std::string& path, std::string_view what) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error(fmt::format("{}: cannot open {}", path, what));
    std::ostringstream text;
    text << in.rdbuf();
    return text.str();
  }

  toml::table Parse(std::string_view text) const {
    try {
      return toml::parse(text, source_);
    } catch (const toml::parse_error& e) {
      throw Error(fmt::format("{}:{}:{}: TOML syntax: {}", source_, e.source().begin.line, e.source().begin.column,
                              e.description()));
    }
  }

  [[noreturn]] void Fail(const toml::node& n, const std::string& what) const {
    throw Error(fmt::format("{}:{}: {}", source_, n.source().begin.line, what));
  }
  [[noreturn]] void Fail(const std::string& what) const { throw Error(fmt::format("{}: {}", source_, what)); }

  void RefuseUnknown(const toml::table& t, std::string_view where, std::initializer_list<const char*> keys) const {
    for (auto&& [k, v] : t) {
      if (std::find_if(keys.begin(), keys.end(), [&](const char* key) { return k.str() == key; }) == keys.end())
        Fail(v, fmt::format("{}unknown key '{}' (known: {})", where, k.str(), fmt::join(keys, ", ")));
    }
  }
  std::optional<double> Number(const toml::table& t, std::string_view where, const char* key) const {
    const toml::node* n = t.get(key);
    if (!n) return std::nullopt;
    if (!n->is_number()) Fail(*n, fmt::format("{}{} must be a number", where, key));
    const double v = *n->value<double>();
    if (!std::isfinite(v)) Fail(*n, fmt::format("{}{} must be finite", where, key));
    return v;
  }
  std::optional<std::int64_t> Integer(const toml::table& t, std::string_view where, const char* key) const {
    const toml::node* n = t.get(key);
    if (!n) return std::nullopt;
    if (!n->is_integer()) Fail(*n, fmt::format("{}{} must be an integer", where, key));
    return *n->value<std::int64_t>();
  }
  std::optional<std::string> Text(const toml::table& t, std::string_view where, const char* key) const {
    const toml::node* n = t.get(key);
    if (!n) return std::nullopt;
    if (!n->is_string()) Fail(*n, fmt::format("{}{} must be a string", where, key));
    return *n->value<std::string>();
  }
  std::optional<bool> Bool(const toml::table& t, std::string_view where, const char* key) const {
    const toml::node* n = t.get(key);
    if (!n) return std::nullopt;
    if (!n->is_boolean()) Fail(*n, fmt::format("{}{} must be true or false", where, key));
    return *n->value<bool>();
  }

 private:
  std::string source_;
};

}  // namespace strut::rig
