// Finding the missing physics: when a fitted model and the recordings differ by more than the
// measurement noise explains, locate the mismatch, name the catalogue term whose signature it
// matches, add it, refit, and keep it only where the fit improves beyond what it costs.
#pragma once

#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "strut/ident/decisive_test.h"
#include "strut/ident/estimator.h"
#include "strut/ident/session_fit.h"

namespace strut::ident {

struct DiscoverOptions {
  //! A term is kept when BIC falls by more than this (10: "very strong" evidence).
  double bic_threshold = 10.0;
  //! Discovery stops when the fit is at the noise floor: no channel's pooled noise ratio above what
  //! noise alone reaches (FitChannel::AboveNoiseFloor, kNoiseFloorFalseAlarm).
  //! A kept term must also take away misfit: the mean over the channels of the noise ratio's excess
  //! over 1 falls to this fraction or less, and some channel's ratio falls by more than its sampling
  //! noise puts between two fits (NoiseFloorLimit's z times the ratio's sd).
  double min_improvement = 0.95;
  //! Cross-validation: the experiments are split into this many folds; a kept term must also
  //! predict every fold's experiments, fitted without them, better than the current model does
  //! (its held-out noise ratio at most `cv_improvement` times the current one). 0: no cross-validation.
  //! A candidate also passes when it predicts the held-out experiments better one by one: the
  //! Wilcoxon signed-rank test of their paired log ratios (candidate over current) rejects "no
  //! better" at this level (SignedRankPValue). The median alone misses a term that takes the worst
  //! predictions down tenfold while the middle ones move by their noise.
  int cv_folds = 4;
  double cv_improvement = 0.98;
  double cv_alpha = 0.05;
  int max_terms = 8;
  //! Screening: a candidate whose size score t (CandidateStart::size_score, the located mismatch's
  //! regression) cannot lower the BIC by bic_threshold even at `screen_margin` times its first-order
  //! fall, screen_margin t^2 < bic_threshold + k log(observations) for its k new parameters, is not
  //! refitted. 0: every candidate is refitted.
  double screen_margin = 4.0;
  //! Threads: candidate refits and cross-validation folds side by side, and each fit's experiments
  //! too (EstimatorOptions::threads). The answers are the same for any count.
  int threads = 2;
  //! When no catalogue term explains what is left above the noise floor, the empirical discrepancy
  //! (DiscrepancyLibrary) takes its place: its functions are added one at a time by the same rules
  //! (BIC, noise ratio, held-out prediction), at most `max_discrepancy_functions`; per round the
  //! `discrepancy_refits` largest size scores are refitted. Never named as a catalogue term.
  bool discrepancy = true;
  int max_discrepancy_functions = 6;
  int discrepancy_refits = 4;
  //! A catalogue term is named only when no function of the library explains the data better: in
  //! the round that keeps a term, the functions that do not share its signature (those whose
  //! `resembles` is another term or none) are refitted beside it, and one whose BIC falls below the
  //! term's by more than bic_threshold, and that predicts the left-out experiments better than the
  //! current model, is kept instead, empirical. A term that fits only because it stands in for
  //! physics the catalogue lacks (a charge lost over the session standing in for a real gas, whose
  //! departure follows the recording order of the standard matrix) is then not named.
  bool challenge_terms = true;
  //! Catalogue terms discovery does not propose (the leave-one-out study conceals them this way).
  std::vector<std::string> leave_out;
  //! Honest ambiguity (docs/discovery.md "Explanations that fit alike"): a rival of a kept term (a
  //! candidate of its round that passed the BIC and noise-ratio rules and was not refused by the
  //! held-out test) explains the data alike when the final model with the rival in the kept term's
  //! place has a BIC less than `ambiguity_bic_margin` above the final model's (10: short of "very
  //! strong" evidence on Kass and Raftery's scale, the margin a term must clear to be kept), or when
  //! the two terms fitted together have sizes correlated beyond `ambiguity_correlation` (the data
  //! move one into the other). Each ambiguity gets the test that decides (ProposeDecisiveTest) from
  //! `test_space` (default: TestSpaceOf the recorded experiments).
  bool ambiguity = true;
  double ambiguity_bic_margin = 10.0;
  double ambiguity_correlation = 0.95;
  std::optional<TestSpace> test_space;
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
  //! Noise ratio of the experiments left out of the fit, over all folds (NaN: not cross-validated)
  double cv_ratio = NAN;
  std::string verdict;     //!< kept, or why not ("BIC", "noise ratio", "cross-validation", "no solution")
  bool screened = false;   //!< not refitted: its size score says it cannot pay for its parameters
  double size_score = NAN; //!< CandidateStart::size_score
  //! Passed the BIC and noise-ratio rules (the held-out test then decides between those).
  bool qualified = false;
};

struct DiscoveryStep {
  std::string term;        //!< a catalogue term, or "discrepancy:NAME" (empirical)
  bool empirical = false;  //!< a function of the empirical discrepancy, not a catalogue term
  //! A catalogue term taken out again once the empirical discrepancy was in: without it the BIC
  //! rises by less than the threshold (delta_bic: without minus with), so the data do not support it.
  bool removed = false;
  std::string evidence;
  double delta_bic = 0.0;
  std::map<std::string, double> noise_before, noise_after;
  std::vector<std::pair<std::string, double>> parameters;  //!< the term's fitted sizes: key, value
  std::vector<CandidateFit> candidates;                     //!< every candidate of this round
  double cv_before = NAN, cv_after = NAN;                   //!< held-out noise ratio, current model and with the term
};

//! One function of the empirical discrepancy that discovery selected, with its fitted coefficient.
struct DiscrepancyTerm {
  int index = 0;          //!< theta<index>
  std::string name;       //!< the library's name, e.g. "damping-direction"
  std::string shape;      //!< the function in symbols and words
  std::string resembles;  //!< the catalogue term whose signature it shares ("" none)
  double value = 0.0, sd = NAN;
};

//! What no catalogue term explained, as an empirical sum of library functions: marked empirical,
//! never a catalogue name. `dependence` says in words what the missing force (or gas) depends on.
struct EmpiricalDiscrepancy {
  std::vector<DiscrepancyTerm> functions;  //!< in the library's order
  std::vector<std::string> dependence;     //!< e.g. "damping in extension 2.4 times compression at 0.20 m/s"
  std::vector<std::string> resembles;      //!< catalogue terms whose signatures the functions share
  //! The missing force against the stroke rate at the middle static position, per direction, and
  //! against the stroke at the median peak rate, per direction: what the report plots.
  struct Curve {
    std::string label;  //!< e.g. "against rate, compression"
    std::vector<double> x, force;
  };
  std::vector<Curve> curves;
};

//! A model that explains the data about as well as the one discovery chose: the final model with a
//! rival term in the place of a kept one.
struct RivalExplanation {
  std::string term;   //!< the rival catalogue term
  std::string model;  //!< the final model with `term` in the kept term's place
  double delta_bic = NAN;  //!< its BIC minus the final model's (NaN: not fitted)
  std::map<std::string, double> noise_ratio;
  bool at_noise_floor = false;
  //! The largest correlation between the kept term's and the rival's sizes, the two fitted together
  //! (NaN: that fit did not converge).
  double correlation = NAN;
  std::string why;   //!< why it counts as alike, in words ("" when it does not)
  FitSummary fit;    //!< the rival model's fit (what the decisive test predicts with)
};

//! Explanations the data cannot tell apart: the kept term and its rivals, with the test that decides.
struct Ambiguity {
  std::string kept;  //!< the term discovery kept
  int step = 0;      //!< its index in DiscoveryResult::steps
  std::vector<RivalExplanation> rivals;  //!< those that explain the data alike
  std::optional<DecisiveTest> test;      //!< between the final model and the first rival
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
  //! Set when discovery had to model what is left empirically (DiscoverOptions::discrepancy).
  std::optional<EmpiricalDiscrepancy> discrepancy;
  //! Kept terms whose rivals explain the data alike (DiscoverOptions::ambiguity): never one chosen silently.
  std::vector<Ambiguity> ambiguities;
  //! Set by the caller that ran the first ambiguity's decisive test and fitted its explanations with
  //! it (Decide; strut discover --decide).
  std::optional<Decision> decision;
  std::string conclusion;            //!< one paragraph for people
};

//! The first ambiguity that has a decisive test (nullptr: none).
const Ambiguity* DecidableAmbiguity(const DiscoveryResult& result);
//! Decide (decisive_test.h) between the explanations of DecidableAmbiguity (the final model and its
//! rivals' models) with data that hold its test: what `strut discover --decide` concludes.
//! Throws std::invalid_argument when nothing is decidable.
Decision DecideAmbiguity(const DiscoveryResult& result, const FitData& with_test, const SessionFitOptions& fit,
                         const DiscoverOptions& options);

//! Per channel: the pooled noise ratio (FitChannel::noise_ratio) of a fit.
std::map<std::string, double> PooledNoiseRatio(const FitSummary& fit);

//! The located features of a fit's residuals (needs stroke, force and pressure measured).
std::vector<Finding> LocateMismatch(const FitSummary& fit);

//! The held-out noise ratio of a composition under K-fold cross-validation: for each fold, the model
//! refitted (from `fit`'s values, the same parameters estimated) without the fold's experiments
//! predicts them. Each held-out experiment's residuals over the noise of the averaged data, all
//! channels pooled, give its noise ratio; the result is the median of those over all experiments
//! (robust to the one experiment that alone shows an effect). NaN when a refit or a prediction has
//! no solution. The folds are refitted `threads` at a time (the same answer for any count).
double CrossValidatedNoiseRatio(const FitData& data, const Model& model, const FitSummary& fit,
                                const EstimatorOptions& estimator, int folds, int threads = 1);

//! The exact one-sided p-value of Wilcoxon's signed-rank test that paired `differences` centre below
//! 0: the probability, with every sign equally likely, of a sum of the positive differences' ranks
//! (mid-ranks for ties of |d|; zeros left out) at most the observed one. 1 without nonzero differences.
double SignedRankPValue(const std::vector<double>& differences);

//! The empirical discrepancy of a fit whose model has the discrepancy term: the functions whose
//! coefficients it estimated (the others are 0), what the missing force depends on in words, and
//! its curves. Empty functions when the fit has no discrepancy.
EmpiricalDiscrepancy DescribeDiscrepancy(const FitSummary& fit);

//! Runs discovery from the baseline `fit.composition` (any composition; its fit is the full default
//! fit of SessionFitOptions) on prepared experiments.
DiscoveryResult Discover(const FitData& data, const SessionFitOptions& fit, const DiscoverOptions& options,
                         const std::function<void(const std::string&)>& progress = {});

}  // namespace strut::ident
