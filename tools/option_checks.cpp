#include "option_checks.h"

#include <fmt/format.h>

#include <cmath>
#include <functional>

namespace strut::tools {
namespace {

// A bound as people write it: 100000, not 1e+05; 0.001, not 1.000000e-03.
std::string Number(double x) {
  if (x == std::floor(x) && std::fabs(x) < 1e15) return fmt::format("{:.0f}", x);
  return fmt::format("{:g}", x);
}

std::string WithUnit(std::string range, const std::string& unit) { return unit.empty() ? range : range + " " + unit; }

CLI::Validator NumberCheck(const std::string& range, std::function<bool(double)> inside) {
  return CLI::Validator(
      [range, inside](std::string& text) -> std::string {
        double value = NAN;
        if (!CLI::detail::lexical_cast(text, value) || !std::isfinite(value))
          return fmt::format("'{}' is not a number; give a number {}", text, range);
        if (!inside(value)) return fmt::format("{} is out of range; give a number {}", text, range);
        return {};
      },
      range, "range");
}

class Formatter : public CLI::Formatter {
 public:
  std::string make_option_opts(const CLI::Option* opt) const override {
    if (!opt->get_option_text().empty() || opt->get_type_size() == 0 || opt->get_default_str().empty())
      return CLI::Formatter::make_option_opts(opt);
    std::string text = CLI::Formatter::make_option_opts(opt);
    const std::string with_default = "=" + opt->get_default_str();
    const auto at = text.find(with_default);
    if (at != std::string::npos) text.replace(at, with_default.size(), " (default " + opt->get_default_str() + ")");
    return text;
  }
};

}  // namespace

CLI::Validator Positive(const std::string& unit) {
  return NumberCheck(WithUnit("> 0", unit), [](double x) { return x > 0; });
}

CLI::Validator NonNegative(const std::string& unit) {
  return NumberCheck(WithUnit(">= 0", unit), [](double x) { return x >= 0; });
}

CLI::Validator Between(double low, double high, const std::string& unit) {
  return NumberCheck(WithUnit(Number(low) + " .. " + Number(high), unit),
                     [low, high](double x) { return x >= low && x <= high; });
}

std::shared_ptr<CLI::Formatter> HelpFormatter() { return std::make_shared<Formatter>(); }

}  // namespace strut::tools
