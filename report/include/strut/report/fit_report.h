// A fit for machines (JSON) and for people (one self-contained HTML report).
#pragma once

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "strut/ident/estimator.h"
#include "strut/ident/fit_record.h"
#include "strut/ident/model.h"

namespace strut::report {




class HtmlReport;

//! model, converged, iterations, parameters, channels, experiments, loglik, aic, bic, warnings,
//! correlation, history (docs/identification.md lists every field).
nlohmann::json FitToJson(const ident::FitSummary& fit);


//! The identification report (docs/reports.md): the verdict first, then parameters with ± sd and
//! intervals, channels, residual means with 2 sigma per experiment (paper Figs. 8 and 11),
//! correlation, convergence, and per experiment the overlays beside their residuals and the loops.
//! One set of units throughout: mm, kN, MPa, °C (DisplayUnitOf).
void WriteFitReport(const ident::FitSummary& fit, const std::string& path, const std::string& title);

//! How a quantity is shown in reports: shown = value * scale + offset, in `unit`.
struct DisplayUnit {
  double scale = 1.0, offset = 0.0;
  std::string unit;
  double Value(double si) const { return si * scale + offset; }
};
//! The report's unit for an SI unit: m as mm, N as kN, Pa as MPa; any other unit as it is.
DisplayUnit DisplayUnitOf(const std::string& si_unit);
//! The report's unit for a recorded channel: stroke mm, force kN, pressure MPa, temperature °C;
//! a generic model's channel (u, y) as recorded, with no unit.
DisplayUnit ChannelDisplayUnit(const std::string& channel);
//! "quantity [unit]", or the quantity alone when the unit is empty.
std::string AxisLabel(const std::string& quantity, const DisplayUnit& unit);

// Sections of the identification report, shared with the discovery report.
void AddVerdict(HtmlReport& report, const ident::FitSummary& fit);         //!< VerdictText as a coloured call-out
void AddParameterTable(HtmlReport& report, const ident::FitSummary& fit);  //!< value ± sd, interval, misfit widening
void AddChannelTable(HtmlReport& report, const ident::FitSummary& fit);    //!< rms, variances, noise ratio per channel
void AddResidualBars(HtmlReport& report, const ident::FitSummary& fit);    //!< residual mean ± 2σ per experiment
//! Per experiment: each fitted channel's overlay (measured dots, predicted line) beside its residual
//! over the period with the ± 2σ noise band, then the force- and pressure-stroke loops.
void AddExperimentPlots(HtmlReport& report, const ident::FitSummary& fit);
//! Per experiment and estimated parameter: sd without it over the sd of the fit, and its information share.
void AddContributionTable(HtmlReport& report, const ident::FitSummary& fit);
//! Per drop: each fitted channel's record and prediction from contact beside the residual.
void AddTransientPlots(HtmlReport& report, const ident::FitSummary& fit);

}  // namespace strut::report
