// Transient (drop) experiments in the multi-experiment fit: the recorded data and the extension
// point that predicts them. ident cannot integrate a drop (that is sim's transient integrator), so
// the estimator takes a factory of TransientExperimentPredictor (EstimatorOptions::
// transient_predictor) the way it takes one for periodic experiments; sim/drop_fit.h implements it
// with IDAS forward sensitivities and tools/ wires it in. docs/drop-prediction.md, "Drop records
// in the fit".
#pragma once

#include <Eigen/Core>
#include <functional>
#include <map>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "strut/daq/session.h"
#include "strut/ident/model.h"

namespace strut::ident {

//! One recorded channel of a transient experiment.
struct TransientChannel {
  Eigen::VectorXd samples;  //!< SI at TransientExperimentData::time (pressure absolute)
  //! Per-sample noise variance: the spread about a quadratic trend over the record's last second,
  //! where the mass is at rest and only the gas is still cooling (NaN: the record is too short).
  double noise_variance = NAN;
};

//! A recorded drop ready for fitting (session-format.md, kind "drop"). Time 0 is contact.
struct TransientExperimentData {
  std::string session;  //!< file it came from
  std::string label;
  std::string kind = "drop";
  double drop_mass = 0.0;        //!< kg
  double impact_velocity = 0.0;  //!< m/s at contact
  std::vector<double> time;      //!< s from contact, increasing
  //! The fitted channels by name (TransientFitChannels(), the ones recorded and not excluded).
  std::map<std::string, TransientChannel> channels;
};

//! The channels a drop is fitted on: the outputs of the force-driven model, the stroke (with the
//! sensor zero theta12) and the gas pressure. The drop rig's force is the load of the mass
//! M (g - q''), not a model output; it is left to `strut predict drop --compare`.
const std::vector<std::string>& TransientFitChannels();

//! The fit's name of a transient experiment's channel: "drop:stroke". Its variance is estimated
//! apart from the periodic experiments' (a drop is raw samples at its own rate, the periodic
//! experiments period averages), pooled over the drops of the fit.
std::string TransientChannelName(const std::string& kind, const std::string& channel);

//! The drop experiments of a session (complete ones; aborted ones are skipped with a log line).
//! `name` stands for the file in messages. Throws daq::SessionError naming the file, experiment and
//! channel for unusable data: no stroke, non-finite samples, a time that does not start at 0 or
//! does not increase, a mass or impact velocity that is missing or not positive.
std::vector<TransientExperimentData> PrepareTransientExperiments(const daq::Session& session, const std::string& name);

//! A transient experiment's prediction at one parameter vector.
struct TransientPrediction {
  std::vector<std::string> channels;  //!< rows of `outputs` (Model::output_channels of the force-driven model)
  Eigen::MatrixXd outputs;            //!< channels x samples, at the data's times
  //! Per channel, samples x parameters asked for (d output / d theta); empty when none were asked.
  std::vector<Eigen::MatrixXd> sensitivities;
};

//! No prediction at these parameters (the integration failed); the fit leaves the experiment out
//! like a periodic experiment without a solution.
class TransientPredictionError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

//! Predicts one recorded transient experiment. One instance per experiment (the estimator's
//! factory makes one each); not thread-safe.
class TransientExperimentPredictor {
 public:
  virtual ~TransientExperimentPredictor() = default;
  //! The outputs at the data's sample times for `theta` (all of the model's parameters) and, for
  //! the positions in `parameters` (may be empty), their exact sensitivities. Throws
  //! TransientPredictionError.
  virtual TransientPrediction Predict(std::span<const double> theta, std::span<const int> parameters) = 0;
};

//! Makes the predictor of one experiment for the fitted model (in whatever causality it is fitted).
using TransientPredictorFactory =
    std::function<std::unique_ptr<TransientExperimentPredictor>(const Model&, const TransientExperimentData&)>;

}  // namespace strut::ident
