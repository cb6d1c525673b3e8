// Starting values from the data itself, and the paper's friction pre-identification (Fig. 7).
#pragma once

#include <string>
#include <vector>

#include "strut/ident/experiment_data.h"
#include "strut/ident/model.h"
#include "strut/ident/parameters.h"

namespace strut::ident {

//! The friction found at one velocity reversal.
struct FrictionReversal {
  std::string experiment;
  bool top = true;          //!< at full compression of the cycle (velocity + to -), else at extension
  double pressure = 0.0;    //!< absolute gas pressure at the reversal, Pa
  double amplitude = 0.0;   //!< arctan amplitude theta8 + theta9 p, N (force jump = pi * amplitude)
  double sharpness = 0.0;   //!< arctan sharpness, s/m
  double rms = 0.0;         //!< rms of the local fit, N
};

//! theta8..theta10 from the force jumps at velocity reversals (paper section 6, Fig. 7).
struct FrictionEstimate {
  bool ok = false;
  double base = 0.0;          //!< theta8, N
  double per_pressure = 0.0;  //!< theta9, m^2
  double sharpness = 0.0;     //!< theta10, s/m
  std::vector<FrictionReversal> reversals;
  std::string note;           //!< why not ok, or what was assumed
};

//! Fits, around every velocity reversal of every experiment, the local force
//! F = c0 + c1 q + c2 q'' + A atan(s q') (gas force linear in stroke, inertia, friction) with the
//! velocity and acceleration from the noise-thresholded Fourier series of the stroke; then
//! A = theta8 + theta9 p over all reversals by least squares, and theta10 the median sharpness.
//! Needs stroke, force and pressure channels.
FrictionEstimate PreidentifyFriction(const std::vector<ExperimentData>& data);

//! Starting values for every parameter of `model`: the static force-stroke-pressure relation of
//! the slowest experiment (gas area, charge, volume change, exponent, force offset), friction from
//! the reversals, and physical defaults where the data cannot say. `log` says where each came from;
//! `sources`, per parameter position, the same in a few words ("physical default", ...).
ParameterSet InitialValuesFromData(const Model& model, const std::vector<ExperimentData>& data,
                                   std::vector<std::string>* log, std::vector<std::string>* sources = nullptr);

//! Starting values of a linear-oscillator model from periodic experiments: the equation-error
//! least-squares fit of  u = theta50 y'' + theta51 y' + theta52 y [+ theta53 y^2] [+ theta54 y^3]
//! [+ theta58 y'^3] [+ theta55]  over all experiments, with y and its derivatives from the Fourier series of the
//! averaged output (the harmonics above the noise, differentiated exactly) and u the averaged
//! input at the same phases. With output-offset and no input-offset, the constant of the fit gives
//! theta56 = -constant / theta52; otherwise theta56 starts at 0. Needs the model's channels (y, u)
//! in every experiment; throws std::invalid_argument naming the experiment otherwise. `log` gets
//! one line per parameter.
ParameterSet OscillatorInitialValues(const Model& model, const std::vector<ExperimentData>& data,
                                     std::vector<std::string>* log = nullptr);

}  // namespace strut::ident
