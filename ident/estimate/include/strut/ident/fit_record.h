// A fit read back from its JSON record (`strut identify --json`, written by report::FitToJson):
// what a prediction, a safety limit or a comparison with a reference unit needs.
#pragma once

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "strut/ident/model.h"
#include "strut/ident/parameters.h"

namespace strut::ident {

//! The parts of a fit's record that a prediction or a comparison with a reference unit needs.
struct FitRecord {
  std::string source;  //!< the file, for messages
  Model model;         //!< the fitted composition, in the causality asked for
  ParameterSet parameters;  //!< the model's parameters at the fitted values
  std::vector<int> estimated_positions;  //!< positions (in `parameters`) of the estimated ones
  //! Posterior covariance among the estimated parameters (sd_a sd_b correlation_ab), in the order
  //! of estimated_positions.
  Eigen::MatrixXd covariance;
  bool converged = false;
  std::string verdict;  //!< "at-noise-floor", "above-noise-floor" or "not-converged"
};

//! Parses a fit's JSON. Throws std::invalid_argument naming `source` and the item: not JSON, no
//! model, an unknown parameter, a missing or non-finite value or sd of an estimated parameter, a
//! correlation matrix that does not match the estimated parameters.
FitRecord ParseFitJson(const nlohmann::json& j, const std::string& source, Causality causality);
//! Reads and parses a fit's JSON file (std::invalid_argument naming the file when unreadable).
FitRecord ReadFitJson(const std::string& path, Causality causality);

}  // namespace strut::ident
