#pragma once

#include <optional>
#include <string_view>
#include <vector>

namespace strut::ident {

//! One NAME=VALUE item of a comma-separated list; blanks around the name and the value dropped.
struct Assignment {
  std::string_view item, name, value;
};

//! Splits "NAME=VALUE[,NAME=VALUE...]" (--set, --calibration) at commas and each item at its first
//! '='. Blank text gives no items. An empty item (two commas, or one at an end) throws
//! ParameterError naming the text, an item without '=' or without a name one naming the item, both
//! prefixed by `option`; `form` says what an item should look like. Views into `text`.
std::vector<Assignment> SplitAssignments(std::string_view text, std::string_view option, std::string_view form);

//! A finite number filling all of `text` (blanks around it allowed); nullopt otherwise (out of range too).
std::optional<double> ParseNumber(std::string_view text);

}  // namespace strut::ident
