// Finding the missing physics: when a fitted model and the recordings differ by more than the
// measurement noise explains, locate the mismatch, name the catalogue term whose signature it
// matches, add it, refit, and keep it only where the fit improves beyond what it costs.
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

#include "strut/ident/estimator.h"

namespace strut::ident {

struct DiscoverOptions {
  EstimatorOptions estimator;
  //! A term is kept when BIC falls by more than this (10: "very strong" evidence).
  double bic_threshold = 10.0;
  //! Nothing is missing when every channel's residual variance is below this many times its
  //! noise floor (the ratio of a correct model scatters around 1).
  double noise_ratio_threshold = 1.5;
  //! A kept term must also lower the mean noise ratio over the channels to this fraction or less.
  double min_improvement = 0.95;
  int max_terms = 8;
  int threads = 2;  //!< candidate refits in parallel
  bool IsValid(std::string* error) const;
};

//! One located feature of the residuals (in units of the noise of the averaged data).
struct Finding {
  std::string locus;    //!< group-bias, loop-frequency, velocity, reversal, extension, pressure-stiffening, ...
  std::string channel;
  double score = 0.0;   //!< strength of the feature (signal-to-noise of the statistic)
  std::string detail;   //!< where and how large, in words
};

struct CandidateFit {
  std::string term;
  bool ok = false;
  std::string error;
  double delta_bic = 0.0;  //!< candidate BIC - current BIC (negative: better)
  double evidence = 0.0;   //!< score of the term's locus in the current residuals
  std::map<std::string, double> noise_ratio;  //!< per channel after the refit
};

struct DiscoveryStep {
  std::string term;
  std::string evidence;
  double delta_bic = 0.0;
  std::map<std::string, double> noise_before, noise_after;
  std::vector<std::pair<std::string, double>> parameters;  //!< the term's fitted sizes: key, value
  std::vector<CandidateFit> candidates;                     //!< every candidate of this round
};

struct DiscoveryResult {
  FitSummary baseline;
  std::vector<Finding> mismatch;     //!< located in the baseline residuals, strongest first
  bool nothing_missing = false;      //!< the baseline explains the data to the noise floor
  std::vector<std::string> missing;  //!< catalogue terms added, in order
  std::string final_model;
  FitSummary final_fit;
  std::vector<DiscoveryStep> steps;
  std::vector<Finding> unexplained;  //!< what the final model leaves above the noise, if anything
  std::string conclusion;            //!< one paragraph for people
};

//! Per channel: residual mean square over the noise variance of the averaged data, pooled over
//! the experiments that were fitted.
std::map<std::string, double> PooledNoiseRatio(const FitSummary& fit);

//! The located features of a fit's residuals (needs stroke, force and pressure measured).
std::vector<Finding> LocateMismatch(const FitSummary& fit);

//! Runs discovery from `base` (any composition) on prepared experiments.
DiscoveryResult Discover(const std::vector<ExperimentData>& data, const std::string& base, Causality causality,
                         const DiscoverOptions& options, const std::vector<DataIssue>& issues = {},
                         const std::function<void(const std::string&)>& progress = {});

}  // namespace strut::ident
