// The checks of SetPoint::IsValid with the field they are about, so that the register decoder
// can name the register. Standard library only: the libFuzzer target compiles it with clang alone.
#pragma once

#include <optional>
#include <string>
#include <string_view>

#include "strut/daq/controller.h"

namespace strut::daq::detail {

struct SetPointProblem {
  std::string_view field;  //!< "mode", "static_position", "amplitude", ..., "stroke_min", ...
  std::string message;
  bool not_finite = false;  //!< NaN or infinity (rather than out of range)
};

//! The first problem of the set-point, or nullopt when it is valid.
std::optional<SetPointProblem> CheckSetPoint(const SetPoint& set_point);

//! A double as text with up to 6 significant digits ("0.034", "5e+04", "nan").
std::string Number(double value);

}  // namespace strut::daq::detail
