// Recorded periodic experiments brought onto the solver grid: the data the estimator fits.
#pragma once

#include <Eigen/Dense>
#include <map>
#include <string>
#include <vector>

#include "strut/daq/session.h"
#include "strut/ident/model.h"
#include "strut/ident/periodic.h"

namespace strut::ident {

//! One measured channel of one experiment, averaged over its periods.
struct GridChannel {
  Eigen::VectorXd mean;          //!< period-synchronous average at the experiment's phases (SI, pressure absolute)
  double noise_variance = NAN;   //!< per-sample noise variance from the spread between periods (NaN: 1 period)
  double mean_noise_variance = NAN;  //!< noise variance of the averaged values: noise_variance / periods
};

//! A data-quality finding (clipping, dropout, outlier) on one channel of one experiment.
struct DataIssue {
  std::string experiment, channel, kind;  //!< kind: "clipped", "dropout", "outliers", "stuck"
  std::string detail;                     //!< for the report, e.g. "312 samples at the ADC limit 0.2640 m"
};

//! One periodic experiment ready for fitting.
struct ExperimentData {
  std::string session;  //!< file it came from
  std::string label;
  std::string group;
  double frequency = 0.0, amplitude = 0.0, static_position = 0.0;
  long periods = 0;
  PeriodicInput input;                          //!< the model input (force or stroke), averaged onto the n-point grid
  //! Cyclic phases in [0, 1) of the averaged samples: the recorded sample phases when a period
  //! holds a whole number of samples (averaging then needs no interpolation), else the grid's.
  std::vector<double> phases;
  std::map<std::string, GridChannel> channels;  //!< every recorded channel at `phases`, by name
};

//! Brings periodic experiments onto an n-point grid for a model's causality. Experiments that are
//! not periodic or are aborted are skipped with a log line. Detects data defects and reports them
//! in `issues` (they are not silently fitted: see the estimator). Throws daq::SessionError or
//! std::invalid_argument naming the session, experiment and channel for unusable data.
std::vector<ExperimentData> PrepareExperiments(const daq::Session& session, Causality causality, int n,
                                               std::vector<DataIssue>* issues = nullptr);

//! Looks for saturated (clipped) stretches, dropouts (runs of exact zeros or NaN-free flat lines),
//! and outliers (samples far from the period-synchronous mean) in one channel of one experiment.
std::vector<DataIssue> InspectChannel(const daq::Experiment& experiment, const daq::Channel& channel);

}  // namespace strut::ident
