// Recorded periodic experiments brought onto the solver grid: the data the estimator fits.
#pragma once

#include <Eigen/Dense>
#include <complex>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "strut/daq/session.h"
#include "strut/ident/model.h"
#include "strut/ident/periodic.h"

namespace strut::ident {

//! A periodic signal as the Fourier series of the harmonics that stand clear of the noise: 6 times
//! the median amplitude of the upper half of the spectrum (which holds only noise). Measured
//! inputs drive the model through their derivatives, and differentiating sample noise would swamp
//! friction and inertia; the series has exact derivatives.
struct PeriodicSeries {
  double frequency = 0.0;                          //!< Hz
  std::vector<std::complex<double>> coefficients;  //!< c_h, h = 0..H (zero for dropped harmonics)
  int kept = 0;                                    //!< harmonics kept above the noise
  //! Every harmonic's coefficient as measured, h = 0..H, before the threshold (the errors-in-variables
  //! estimate of the input starts from the series and is tied to these by their noise).
  std::vector<std::complex<double>> measured;

  //! From one averaged period sampled at `count` equidistant phases starting at phase 0.
  static PeriodicSeries Fit(const Eigen::VectorXd& period, double frequency);
  //! The `derivative`-th time derivative (0, 1, 2) at the `count` equidistant phases tau_i = i / count
  //! (ExperimentData::phases), by one inverse FFT; harmonics at or above count / 2 are left out.
  Eigen::VectorXd OnPhases(int count, int derivative = 0) const;
  //! Values on the n-point grid tau_mu = mu / n, as a solver input.
  PeriodicInput OnGrid(int n) const;
  //! Values at any grid phases (strictly increasing in [0, 1)), as a solver input on that grid.
  PeriodicInput AtPhases(const std::vector<double>& phases) const;
};

//! One measured channel of one experiment, averaged over its periods.
struct GridChannel {
  Eigen::VectorXd mean;          //!< period-synchronous average at the experiment's phases (SI, pressure absolute)
  double noise_variance = NAN;   //!< per-sample noise variance from the spread between periods (NaN: 1 period)
  double mean_noise_variance = NAN;  //!< noise variance of the averaged values: noise_variance / periods
  //! What was added to the transducer's reading to make `mean` (a gauge pressure's 101325 Pa): a
  //! gain error scales `mean - reading_offset`.
  double reading_offset = 0.0;
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
  double sample_rate = 0.0;  //!< Hz, as recorded (the noise_variance is per sample at this rate)
  //! When it was recorded, as a fraction of its session (daq::ExperimentSessionTimes): theta38 of
  //! its solves; with static_position (theta40) its conditions (Model::AtExperiment).
  double session_time = 0.0;
  ExperimentConditions Conditions() const { return {session_time, static_position}; }
  //! The model input (force or stroke) on the experiment's solver grid: n points, or, when a period
  //! holds a whole number of samples, the smallest whole multiple of them that is at least n (a slow
  //! experiment's grid then holds every recorded sample phase).
  PeriodicInput input;
  //! The harmonics the input series keeps (0: its mean) and the noise variance of each of their
  //! real coefficients (in u = c0 + sum a_h cos + b_h sin): the measured input's noise that
  //! reaches the model (errors in variables). NaN variance: one period, unknown.
  std::vector<int> input_harmonics;
  double input_mean_variance = NAN, input_harmonic_variance = NAN;
  //! The input's Fourier coefficients as measured, c_h for h = 0 .. below the Nyquist harmonic of the
  //! averaged record (u = c_0 + sum 2 Re(c_h exp(i 2 pi h tau))), the dropped harmonics included.
  std::vector<std::complex<double>> input_measured;
  //! Cyclic phases in [0, 1) of the averaged samples: the recorded sample phases when a period
  //! holds a whole number of samples (averaging then needs no interpolation), else the grid's.
  std::vector<double> phases;
  std::map<std::string, GridChannel> channels;  //!< every recorded channel at `phases`, by name
};

//! The periodic solver's grid and scheme of a fit that does not choose them. Under stroke input
//! only the gas temperature has a rate, and central4 on the recorded sample phases (at least 200 a
//! period) is both more accurate and cheaper than backward2 on at least 800 (docs/identification.md);
//! under force input the stroke's rates carry the friction jumps, where the central schemes ring,
//! so it keeps the paper's backward2 on 800.
int DefaultGridPoints(Causality causality);
Scheme DefaultScheme(Causality causality);
//! The paper's equidistant grid: the default under force input, and where the thinned sample grid
//! does not serve (no whole number of samples a period, a scheme other than the default).
inline constexpr int kPaperGridPoints = 800;
//! The least grid points a fit prepares its data with for these options (EstimatorOptions::n and
//! ::scheme; 0: the default thinned grid): n when given, else kPaperGridPoints for a scheme other than
//! the causality's default (backward2 on the thinned grid moved theta7 by 0.8 sd), else 0.
int FitGridPoints(int n, std::optional<Scheme> scheme, Causality causality);

//! The grid of a slow experiment by default under stroke input: of its `count` equidistant sample
//! phases, every one where the model may not be smooth and every k-th elsewhere. The step at a
//! sample is at most (count / `points`) times the measured input's speed there (`velocity` at the
//! phases) over half its peak speed, and at least 1: every sample where the stroke is slow (the
//! friction's switch at a reversal, the Stribeck hump), every (count / points)-th where it is fast
//! (the spacing of a `points`-point grid). Every sample within 4 of one where a measured output's
//! second difference exceeds 4 times its noise's is kept too (`outputs`, each with the variance of its
//! averaged samples: a contact or a clipped peak). Steps grow by at most half a sample per sample.
//! Returns the kept phases i / count.
std::vector<double> ThinnedSamplePhases(const Eigen::VectorXd& velocity, int points,
                                        const std::vector<std::pair<const Eigen::VectorXd*, double>>& outputs);

//! Brings periodic experiments onto an n-point grid for a model's causality (n 0: DefaultGridPoints). Experiments that are
//! not periodic or are aborted are skipped with a log line. Detects data defects and reports them
//! in `issues` (they are not silently fitted: see the estimator). Throws daq::SessionError or
//! std::invalid_argument naming the session, experiment and channel for unusable data.
std::vector<ExperimentData> PrepareExperiments(const daq::Session& session, Causality causality, int n,
                                               std::vector<DataIssue>* issues = nullptr);
//! The same for any model: its input channel (Model::input_channel(): force or stroke for
//! dampers, u for a generic oscillator) is the input.
std::vector<ExperimentData> PrepareExperiments(const daq::Session& session, const Model& model, int n,
                                               std::vector<DataIssue>* issues = nullptr);

//! Looks for saturated (clipped) stretches, dropouts (runs of exact zeros or NaN-free flat lines),
//! and outliers (samples far from the period-synchronous mean) in one channel of one experiment.
std::vector<DataIssue> InspectChannel(const daq::Experiment& experiment, const daq::Channel& channel);

}  // namespace strut::ident
