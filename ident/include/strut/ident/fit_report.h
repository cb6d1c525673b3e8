// A fit for machines (JSON) and for people (one self-contained HTML report).
#pragma once

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "strut/ident/estimator.h"
#include "strut/ident/model.h"

namespace strut::ident {

//! model, converged, iterations, parameters, channels, experiments, loglik, aic, bic, warnings,
//! correlation, history (docs/identification.md lists every field).
nlohmann::json FitToJson(const FitSummary& fit);

//! A fit read back from the JSON of FitToJson (`strut identify --json`): what a prediction or a
//! comparison with a reference unit needs.
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

//! The identification report: time traces, loops, residual means with 2 sigma per experiment
//! (paper Figs. 8 and 11), parameter table with intervals, correlation heat map, convergence.
void WriteFitReport(const FitSummary& fit, const std::string& path, const std::string& title);

}  // namespace strut::ident
