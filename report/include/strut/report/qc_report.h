// A QC decision for machines (JSON) and for people (HTML).
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "strut/ident/session_fit.h"
#include "strut/qc/decision.h"

namespace strut::report {

//! verdict, reasons, serial, session, reference, model, fit_verdict, seconds, quantities (name,
//! unit, value, sd, nominal, lower, upper, status, meaning), data_issues.
nlohmann::json QcToJson(const qc::Decision& decision);
//! A self-contained HTML report: verdict, reasons, the quantities against their bands, the fit.
void WriteQcReport(const qc::Decision& decision, const ident::SessionFit* fit, const std::string& path);

}  // namespace strut::report
