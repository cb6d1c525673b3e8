// Identification of drawn units (`strut bench units`, sim::DrawUnit), none of them the model's
// defaults. Per unit: the standard matrix on the simulated rig, the default fit (every parameter
// the data determine, starting values from the data), the truth's place in the 95 % intervals,
// the noise-floor verdict, and a second fit from a start up to `start_off` off in every estimated
// parameter, which must reach the same optimum.
#pragma once

#include <functional>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "strut/ident/estimator.h"
#include "strut/ident/session_fit.h"
#include "strut/sim/truth.h"
#include "strut/study/statistics.h"

namespace strut::study {

struct UnitsOptions {
  int units = 50;
  unsigned long first_seed = 1000;
  std::string base = "2dof";  //!< the units' physics and the fitted model
  bool servo = false;                //!< drive through the servo actuator (else an ideal one)
  bool shipped_calibration = false;  //!< keep the shipped transducers' zero and gain errors
  bool drawn_gains = false;  //!< each unit's force, pressure and stroke gains drawn around 1 with kLabGainSd
  //! The calibration the fit's intervals hold (ident::ParseGainSd): the lab's by default.
  std::map<std::string, double> gain_sd = ident::kLabGainSd;
  double start_off = 0.3;            //!< largest relative offset of the restart
  std::vector<std::string> effects;  //!< physics the units have and the fitted model lacks
  //! Each unit also draws 1 to this many further effects, at random among those that compose with
  //! the base (sim::ExtraEffects()), from a stream of its own (0: none).
  int effects_per_unit = 0;
  //! Fit each unit with its truth's composition (the base and all its effects) rather than the base.
  bool fit_truth = false;
  //! Before the fit, the top-out reference on the unit's served rig (stroke_zero.h), its stroke
  //! zero recorded in the unit's session: theta12's prior, as `strut rig run` gives it.
  bool top_out = false;
};

//! One unit's fit.
struct UnitFit {
  unsigned long seed = 0;
  std::string truth_composition;  //!< the unit's physics (its truth model)
  ident::FitVerdict verdict = ident::FitVerdict::kNotConverged;
  bool converged = false;
  double worst_noise_ratio = 0.0;  //!< the largest channel noise ratio
  double seconds = 0.0;            //!< wall time of the entry point (prepare, plan, fit)
  std::vector<std::pair<std::string, double>> z;  //!< (estimate - truth) / sd per estimated key the truth has
  std::vector<std::pair<std::string, double>> estimate;  //!< per estimated key
  std::vector<std::pair<std::string, double>> sd;        //!< per estimated key
  double stroke_zero = 0.0, stroke_zero_sd = 0.0;  //!< the top-out reference's (sd 0: none recorded)
  bool restarted = false;  //!< the fit converged, so it was repeated from far off
  bool same_optimum = false;
  double restart_apart_sd = 0.0;  //!< largest |difference| of the two optima in sd
  bool restart_converged = false;
  int restart_iterations = 0;
  std::string restart_warning;  //!< the restart's first warning, if any
  //! CPU on one thread: the entry point; the fit from the data's starting values alone; the same
  //! fit without the calibration in its intervals.
  double cpu = 0.0, estimator_cpu = 0.0, uncalibrated_cpu = 0.0;
};

struct UnitsStudy {
  std::vector<UnitFit> units;
  std::map<std::string, ZCoverage> coverage;  //!< per parameter key
  long pooled_inside = 0, pooled_total = 0;
  long converged = 0, at_floor = 0, same_optimum = 0, restarts = 0;
  double worst_ratio_median = 0.0, worst_ratio_max = 0.0;
  double seconds_median = 0.0;  //!< wall time of the entry point
  //! CPU medians on one thread: the entry point; the fit from the data's starting values alone;
  //! the same fit without the calibration in its intervals; unit by unit the ratio of the two.
  double cpu_median = 0.0, estimator_cpu_median = 0.0, uncalibrated_cpu_median = 0.0, cost_ratio_median = 0.0;
};

//! The truth of the unit of `seed` (drawn around the shipped truth with the options' rig).
sim::Truth DrawnUnitTruth(const UnitsOptions& options, unsigned long seed);

//! Unit `u` (seed first_seed + u): what RunUnitsStudy runs for it, so that a study split into
//! ranges of units (strut batch) gives the same units.
UnitFit FitDrawnUnit(const UnitsOptions& options, int u);
//! The study's figures from its units in unit order (what RunUnitsStudy gives for them).
UnitsStudy SummariseUnits(std::vector<UnitFit> units);

//! A unit in full as a batch shard keeps it, and back (doubles round-trip).
nlohmann::json UnitFitJson(const UnitFit& unit);
UnitFit UnitFitFromJson(const nlohmann::json& j);

//! What `strut bench units` prints: the heading, a line per unit, the summary.
std::string UnitsHeading(const UnitsOptions& options);
std::string UnitLine(const UnitFit& unit);
std::string UnitsSummary(const UnitsOptions& options, const UnitsStudy& study);

//! Runs the study; `on_unit` (may be empty) sees each unit as it ends. The caller checks `gain_sd`
//! against the model (ident::CheckGainChannels).
UnitsStudy RunUnitsStudy(const UnitsOptions& options, const std::function<void(const UnitFit&)>& on_unit = {});

}  // namespace strut::study
