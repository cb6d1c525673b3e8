// A fit for machines (JSON) and for people (one self-contained HTML report).
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "strut/ident/estimator.h"

namespace strut::ident {

//! model, converged, iterations, parameters, channels, experiments, loglik, aic, bic, warnings,
//! correlation, history (docs/identification.md lists every field).
nlohmann::json FitToJson(const FitSummary& fit);

//! The identification report: time traces, loops, residual means with 2 sigma per experiment
//! (paper Figs. 8 and 11), parameter table with intervals, correlation heat map, convergence.
void WriteFitReport(const FitSummary& fit, const std::string& path, const std::string& title);

}  // namespace strut::ident
