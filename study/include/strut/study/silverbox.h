// The Silverbox benchmark (Wigren & Schoukens 2013; shared/data/README.md §2) through the
// periodic identification: classic split, estimation on the steady-state periods of
// realisations 0-8, validation on realisation 9 (periodic prediction), test by simulating the
// arrow from rest (docs/silverbox.md).
#pragma once

#include <Eigen/Dense>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "strut/daq/session.h"
#include "strut/ident/estimator.h"
#include "strut/ident/periodic.h"

namespace strut::study {

//! Sample indices of SNLS80mV (0-based, end excluded), from the data README.
struct SilverboxLayout {
  static constexpr long kArrowStart = 86;             //!< the arrow is [86, 40486)
  static constexpr long kArrowEnd = 40486;
  static constexpr long kTransient = 400;             //!< simulated but not compared (classic split)
  static constexpr long kNoExtrapolationEnd = 32100;  //!< beyond: the arrow exceeds the multisine's amplitude
  static constexpr long kPeriod = 8192;
  static constexpr int kRealisations = 10;            //!< experiments ms0..ms9
};

//! The composition the protocol selected on the estimation and validation data (docs/silverbox.md).
inline constexpr const char* kSilverboxModel =
    "linear-oscillator+quadratic-stiffness+cubic-stiffness+cubic-damping+input-offset";

//! The candidates `strut bench silverbox` compares (docs/silverbox.md): linear, the plain Duffing,
//! the Duffing with a quadratic stiffness (and its equivalent with an output offset instead), and
//! the Duffing with quadratic stiffness and cubic damping.
std::vector<std::string> SilverboxCandidateModels();

struct SilverboxOptions {
  //! Compositions to fit; the one with the lowest validation RMS is tested. One entry: no choice.
  std::vector<std::string> models = {kSilverboxModel};
  //! Grid points per sample of the periodic solver: n = refine * 8192 per period (central4).
  int refine = 4;
  ident::Scheme scheme = ident::Scheme::kCentral4;
  int threads = 0;                   //!< estimator threads (0: one per core)
  int estimation_experiments = 9;    //!< ms0 .. ms(k-1); the classic split uses 9
  int substeps = 8;                  //!< RK4 steps per sample in the arrow simulation
  bool IsValid(std::string* error) const;
};

//! One fitted candidate.
struct SilverboxCandidate {
  std::string model;
  ident::FitSummary fit;
  double fit_seconds = 0.0;      //!< wall time of the estimator (starting values included)
  double fit_cpu_seconds = 0.0;  //!< CPU time of the process during the fit (all threads)
  double estimation_rms_mv = 0.0;
  double validation_rms_mv = 0.0;
  std::vector<std::string> starting_values;  //!< how they were found, one line per parameter
  Eigen::VectorXd validation_measured, validation_predicted;  //!< realisation 9, at its 8192 samples (V)
};

struct SilverboxResult {
  std::vector<SilverboxCandidate> candidates;
  int chosen = 0;  //!< index in candidates: the lowest validation RMS
  double test_arrow_rms_mv = 0.0;                    //!< y[486, 40486)
  double test_arrow_no_extrapolation_rms_mv = 0.0;   //!< y[486, 32100)
  double simulate_seconds = 0.0;
  std::vector<double> arrow_measured, arrow_simulated;  //!< y over the whole arrow [86, 40486), V
  int n = 0;  //!< grid points per period used

  const SilverboxCandidate& best() const { return candidates.at(chosen); }
};

//! Imports SNLS80mV from a directory: the MAT file through libmatio when present, else the CSV,
//! segmented by ImportSpec::Silverbox(). Throws ImportError naming the file.
daq::Session ReadSilverbox(const std::string& directory);

//! Runs the protocol on an imported session (ReadSilverbox or `strut import ... --preset silverbox`).
//! Throws std::invalid_argument naming what is missing from the session.
SilverboxResult RunSilverbox(const daq::Session& session, const SilverboxOptions& options = {});

//! One published result to compare with (data README §2).
struct PublishedResult {
  std::string method, split, test_set;
  double rms_mv = NAN, no_extrapolation_rms_mv = NAN;
  std::string note;
};
//! The results the data README lists, with their splits and caveats.
std::vector<PublishedResult> SilverboxPublishedResults();

//! validation_rms_mv, test_arrow_rms_mv, test_arrow_no_extrapolation_rms_mv, fit_seconds, model,
//! parameters (index, name, unit, value, sd, ci95, estimated), candidates, split, numerics, published.
nlohmann::json SilverboxToJson(const SilverboxResult& result, const SilverboxOptions& options);

//! The HTML report: figures next to the published results, parameters with 95 % intervals,
//! candidates, residual plots (estimation, validation and its spectrum, the arrow). `notes` are
//! added as paragraphs (e.g. the IDA cross-check of the arrow simulation).
void WriteSilverboxReport(const SilverboxResult& result, const SilverboxOptions& options, const std::string& path,
                          const std::vector<std::string>& notes = {});

//! The test simulation cross-checked by SUNDIALS IDA (sim::TransientSimulator, rtol 1e-8) on the
//! chosen model and the same band-limited input as the RK4 run.
struct SilverboxSimulationCheck {
  double seconds = 0.0;  //!< wall time of the IDA run
  long steps = 0;
  double max_difference_uv = 0.0;  //!< largest |IDA - RK4| over the arrow, µV
  double test_arrow_rms_mv = 0.0;  //!< the arrow's test RMS from the IDA run, mV
};
SilverboxSimulationCheck CheckArrowSimulation(const daq::Session& session, const SilverboxResult& result);

}  // namespace strut::study
