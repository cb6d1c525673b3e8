// The discovery report for people (one self-contained HTML file) and its JSON record for
// programs (docs/reports.md).
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "strut/ident/discover.h"

namespace strut::report {

//! The conclusion first, then what was added step by step (signed ΔBIC, noise ratios before and
//! after, the candidates of each round), where the baseline did not fit, the residuals before and
//! after, and the final model's parameter table, channels and overlays, in the identification
//! report's units (mm, kN, MPa, °C). Throws std::runtime_error naming the path when it cannot write.
void WriteDiscoveryReport(const ident::DiscoveryResult& result, const std::string& path);

//! The discovery as `strut discover --json` writes it: the baseline (model, log-likelihood, BIC,
//! noise ratios, verdict), the mismatch found, every step with its candidates, what stays
//! unexplained, the conclusion and the final fit (FitToJson). Non-finite numbers are null.
nlohmann::json DiscoveryJson(const ident::DiscoveryResult& result);

//! When the chain baseline + added terms names the same model as a shorter composition (terms are
//! evaluated in catalogue order, docs/models.md), the sentence that says so, e.g.
//! "1dof+heat-exchange+gas-solubility is the model 2dof ..."; empty otherwise.
std::string CompositionNote(const ident::DiscoveryResult& result);

}  // namespace strut::report
