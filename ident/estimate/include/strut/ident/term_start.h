// Starting values of a candidate term's size and shape parameters from the residuals of a fit
// without it: where discovery's located mismatch (docs/discovery.md) says the term's effect is,
// a linear regression says how large it is.
#pragma once

#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "strut/ident/estimator.h"

namespace strut::ident {

//! Starting values ("theta23", value) for the size and shape parameters (ParameterSpec::sizes_term,
//! shapes_term) of catalogue term `term` when it is added to the model of `baseline` (a stroke-input
//! fit), from the baseline's residuals, measured channels, solutions and parameter values
//! (ExperimentFit::measured, residual, phases, noise_variance, solution). Two ways, both regressions
//! of the residual on the term's sensitivity next to the sensitivities of the parameters the
//! baseline estimated (which absorbed part of the effect), weighted by the noise:
//!  - force terms, on the force equation error (the force residual less theta4 times the pressure
//!    residual: the force balance with the measured pressure), whose sensitivities are closed-form:
//!      viscous-damping  theta18 on the stroke rate (velocity locus)
//!      end-stop         theta21 on the penetration, theta23 the position (0.1 mm grid from 2 mm
//!                       outside to 30 mm inside the least stroke) that leaves the least residual
//!                       (extension locus: the largest stroke from which the force residual grows)
//!  - sizes that act through the gas or the friction level: one Gauss-Newton step from the
//!    baseline with the size at 0 (where the candidate is the baseline, and the residual is nearly
//!    linear in the size), on the exact periodic sensitivities of the force and pressure channels:
//!      oil-compressibility     theta26 (pressure-softening locus)
//!      real-gas                theta31 (pressure-stiffening locus)
//!      dead-volume             theta36 (deep-softening locus)
//!      recoil-damping          theta32 (rate-asymmetry locus)
//!      metering-pin            theta33 (position-damping locus)
//!      friction-asymmetry      theta34 (friction-direction locus)
//!      pressure-heat-transfer  theta35 (loop-pressure locus)
//!      charge-loss             theta37 (session-drift locus)
//!      stribeck-friction    theta19 at each width theta20 of a log grid (0.5 to 40 mm/s, 20 %
//!                           apart); the width that leaves the least residual (reversal locus)
//! Values are clipped into the physical range (a size that regresses negative starts at 0, its
//! neutral). A term with no rule (heat-exchange, gas-solubility, the oscillator terms), one that
//! does not compose with the baseline, or data that cannot say, gives an empty vector or leaves a
//! parameter out: the caller keeps its defaults. `log` (optional) says where each value came from.
//! Costs a fraction of a second for 7 experiments at n = 400 (the Stribeck grid: 25 sensitivity
//! passes). Throws std::invalid_argument for a name not in the catalogue.
struct CandidateStart {
  std::vector<std::pair<std::string, double>> values;  //!< ("theta23", value)
  //! The size's t in its regression (coefficient over standard error, with the residual's own
  //! variance): a score statistic. To first order the size lowers -2 log-likelihood by about t^2
  //! (Gauss-Newton from the baseline), so a small t says the term cannot pay for its parameters.
  //! NaN where the term has no rule or the data cannot say.
  double size_score = NAN;
};
CandidateStart CandidateStartingValues(const std::string& term, const FitSummary& baseline,
                                       std::vector<std::string>* log = nullptr);

//! The starting value and size score of the empirical discrepancy's coefficient theta<index>
//! (DiscrepancyLibrary) when it is added to the fit `baseline` as the stroke-input model `model`
//! (a composition with the discrepancy term): one Gauss-Newton step from the baseline with the
//! coefficient at 0, as for the catalogue's sizes; a function with a shape parameter also gets the
//! shape of a grid whose step leaves the least residual. Empty where `model` lacks the coefficient or
//! the data cannot say.
CandidateStart DiscrepancyStartingValue(const Model& model, int index, const FitSummary& baseline,
                                        std::vector<std::string>* log = nullptr);

}  // namespace strut::ident
