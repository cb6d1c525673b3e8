// Generic forced oscillators (base linear-oscillator, docs/silverbox.md): starting values from
// periodic data, and simulation of a sampled record from rest.
#pragma once

#include <span>
#include <string>
#include <vector>

#include "strut/ident/experiment_data.h"
#include "strut/ident/model.h"
#include "strut/ident/parameters.h"
#include "strut/ident/periodic.h"

namespace strut::study {



//! The periodic solver for linear-oscillator models with a cheaper cold start: instead of the
//! quasi-static guess (a static solve at every grid point, then 4-5 Newton steps) Newton starts
//! from the linear periodic response, each harmonic of the input divided by
//! k - m w^2 + i d w (theta52, theta50, theta51; the input offset taken off the mean), one FFT
//! each way. Warm starts and sensitivities are the solver's own. Models with states (or without
//! the linear-oscillator base) fall back to the solver's cold start.
class OscillatorPredictor : public ident::PeriodicPredictor {
 public:
  OscillatorPredictor(ident::Model model, ident::PeriodicSolverOptions options = {});
  ident::PeriodicSolution Solve(const ident::PeriodicInput& input, std::span<const double> theta,
                         const ident::PeriodicSolution* warm_start = nullptr) override;
  std::vector<Eigen::MatrixXd> OutputSensitivities(const ident::PeriodicSolution& solution, std::span<const double> theta,
                                                   std::span<const int> parameters = {}, bool exact = true) override;
  Eigen::MatrixXd InputGradients(const ident::PeriodicSolution& solution, std::span<const double> theta,
                                 const std::vector<Eigen::MatrixXd>& output_weights) override {
    return solver_.InputGradients(solution, theta, output_weights);
  }
  std::vector<Eigen::MatrixXd> InputSensitivities(const ident::PeriodicSolution& solution, std::span<const double> theta,
                                                  const Eigen::MatrixXd& directions, bool exact = true) override {
    return solver_.InputSensitivities(solution, theta, directions, exact);
  }

 private:
  ident::Model model_;
  ident::PeriodicSolver solver_;
};

//! Band-limited (trigonometric) interpolation of `samples`, taken as one period, onto a grid
//! `factor` times finer: the zero-padded spectrum (the Nyquist bin of an even length split
//! evenly). Sample i of the input is value i * factor of the result.
std::vector<double> BandLimitedUpsample(std::span<const double> samples, int factor);

//! A sampled record (not periodic) on a grid `factor` times finer, band-limited: the record is
//! extended by a raised-cosine blend from its last value back to its first (at least 256 samples,
//! to a fast FFT length) so that its periodic extension has no jump, then BandLimitedUpsample.
//! Value i * factor is sample i; the result covers the extension too.
std::vector<double> BandLimitedRecord(std::span<const double> samples, int factor);

//! Simulates a force-input model without states (a linear-oscillator composition) from rest,
//! driven by a sampled input: classical Runge-Kutta 4 with `substeps` steps per sample, the input
//! between samples by band-limited interpolation (BandLimitedRecord on 2 * substeps points per
//! sample). Rest: the static equilibrium at the first input
//! sample, at zero rate. Returns the output channel (the model's first, e.g. y) at every input
//! sample. Throws std::invalid_argument for other models or bad arguments, std::runtime_error
//! when the solution stops being finite.
std::vector<double> SimulateFromRest(const ident::Model& model, std::span<const double> theta, std::span<const double> input,
                                     double sample_rate, int substeps = 8);

}  // namespace strut::study
