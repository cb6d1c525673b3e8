// The test that decides between two models that explain the recorded data alike: of the sinusoidal
// experiments the rig can run, the one whose predicted outputs under the two fitted models differ
// most over the measurement noise, per minute of rig time.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "strut/ident/estimator.h"
#include "strut/ident/experiment_data.h"
#include "strut/ident/session_fit.h"

namespace strut::ident {

//! The experiments a decisive test may be chosen from (stroke input, SI units) and what a minute of
//! the rig buys. TestSpaceOf(data) keeps inside what the recorded matrix already drove the unit through.
struct TestSpace {
  double stroke_min = 0.0, stroke_max = 0.0;  //!< m: static -+ amplitude stays within
  double max_rate = 0.0;                      //!< m/s: peak stroke rate 2 pi f A at most
  double max_force = 0.0, max_pressure = 0.0; //!< N, Pa (absolute): neither model's prediction beyond
  std::vector<double> frequencies;            //!< Hz, each a whole number of samples a period
  std::vector<double> static_positions;       //!< m
  std::vector<double> amplitudes;             //!< m
  double sample_rate = 0.0;                   //!< Hz
  //! Recorded periods of the test: at least `periods`, more where that many do not reach
  //! `separation_wanted`, at most `max_periods`.
  long periods = 5, max_periods = 60;
  //! The expected chi-square between the two predictions a test should reach: 50 takes the two
  //! models' BIC apart by 40 on average, with an sd of about 2 sqrt(50) = 14, so the decision's
  //! margin of 10 is cleared in nearly every repetition.
  double separation_wanted = 50.0;
  //! Cycles the rig spends besides the recorded periods (ramps in and out, settling to steady
  //! state: docs/rig-run.md), and the speed of its static moves.
  double overhead_cycles = 8.0, static_rate = 0.01;
  //! Per-sample noise sd of each output channel (from the recorded experiments' spread between periods).
  std::map<std::string, double> noise_sd;
  bool IsValid(std::string* error) const;
};

//! The space of the recorded experiments: their stroke range, peak rate, force and pressure, their
//! frequencies, 7 static positions and 5 amplitudes across the stroke range, the median sample rate,
//! and each channel's median per-sample noise sd. Throws std::invalid_argument without experiments.
TestSpace TestSpaceOf(const std::vector<ExperimentData>& experiments);

//! A proposed sinusoidal test and what it is predicted to show.
struct DecisiveTest {
  std::string model_a, model_b;  //!< the two fitted compositions it separates
  double static_position = 0.0, amplitude = 0.0, frequency = 0.0;  //!< m, m, Hz
  long periods = 0;
  double sample_rate = 0.0;
  double minutes = 0.0;     //!< rig time: the static move from the matrix's middle, the overhead cycles and the periods
  //! The expected chi-square between the two models once both are refitted with the test's data (the
  //! linearised criterion of Buzzi-Ferraris and Forzatti): the predictions' difference over the
  //! noise of the averaged test and what each model's parameter posterior lets it move there. Under
  //! one model the other's fit worsens by about this much. What ranks the tests (per minute).
  double separation = 0.0;
  //! The same at the fitted values, parameters held: the sum over every recorded sample and output
  //! channel of (difference / noise sd)^2. An upper bound of `separation`.
  double separation_fixed = 0.0;
  double separation_per_minute = 0.0;
  std::map<std::string, double> rms_difference;  //!< per channel, the predictions' RMS difference in noise sd
  std::map<std::string, double> peak;            //!< the larger of the two predictions' peaks: force N, pressure Pa
  std::string channel;                           //!< the channel that carries most of the separation
  int candidates = 0;                            //!< tests evaluated within the space
  //! The best test in words: what to run and what it shows.
  std::string Describe() const;
};

//! Every test of `space` predicted with both fits (their models under stroke input, at the end of
//! the session: Model::AtExperiment, session time 1), the best separation per minute kept (at space.periods);
//! its periods are then raised towards separation_wanted. nullopt when no test of the space has a
//! solution under both models within the force and pressure limits. `a` and `b` must be fits of
//! damper models with stroke, force and pressure channels.
std::optional<DecisiveTest> ProposeDecisiveTest(const FitSummary& a, const FitSummary& b, const TestSpace& space);

//! Which of several explanations the data (the sessions with the decisive test's added) support:
//! each composition fitted as identify fits it (FitPrepared), the lowest BIC wins when every other
//! lies more than `margin` above it; else the data still do not decide.
struct Decision {
  std::vector<std::string> models;  //!< as given
  std::vector<FitSummary> fits;     //!< per model
  int winner = -1;                  //!< index into models, -1: undecided
  double margin = 10.0;
  double delta_bic = NAN;           //!< the runner-up's BIC minus the winner's (the best's, undecided)
  std::string conclusion;           //!< in words
};
//! `starts` (optional, one per model, null for none): each model's fit of the sessions before the
//! test, from which its fit with the test starts; where that does not converge, it is fitted as
//! identify fits it.
Decision Decide(const FitData& data, const std::vector<std::string>& models, const SessionFitOptions& options,
                double margin = 10.0, int threads = 1, const std::vector<const FitSummary*>& starts = {});
//! The decision from the models' fits: a winner only when every fit converged (a fit that stopped
//! short has a BIC above its model's best, so losing by it rules nothing out).
Decision DecideByBic(const std::vector<std::string>& models, std::vector<FitSummary> fits, double margin = 10.0);

}  // namespace strut::ident
