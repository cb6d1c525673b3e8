// Numeric option ranges that say what they mean. CLI11's own (CLI::PositiveNumber, CLI::Range on
// a double) print the largest double, 309 digits, as an upper bound and a range that includes 0
// for "positive"; these print "> 0 kg" or "16 .. 100000" in --help, and a refusal names the option
// (CLI11 prefixes its name), the value and the range.
#pragma once

#include <CLI/CLI.hpp>
#include <memory>
#include <string>

namespace strut::tools {

//! A finite number > 0; `unit` (e.g. "kg") is printed after the range.
CLI::Validator Positive(const std::string& unit = "");
//! A finite number >= 0.
CLI::Validator NonNegative(const std::string& unit = "");
//! A finite number in [low, high].
CLI::Validator Between(double low, double high, const std::string& unit = "");

//! CLI11's help layout with the default written "(default X)" after the type and range, so that
//! "FLOAT:> 0 kg=350" reads "FLOAT:> 0 kg (default 350)".
std::shared_ptr<CLI::Formatter> HelpFormatter();

}  // namespace strut::tools
