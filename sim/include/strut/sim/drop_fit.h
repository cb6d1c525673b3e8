// Drop records in the fit (docs/drop-prediction.md, "Drop records in the fit"): the transient
// predictor of a recorded drop that the estimator fits beside the periodic experiments
// (ident::TransientExperimentPredictor). The model is integrated in mass-load mode from contact,
// as `strut predict drop` and the simulated rig's drop do, with the outputs' exact sensitivities
// from SUNDIALS IDAS forward sensitivity analysis.
#pragma once

#include <memory>
#include <span>
#include <string>
#include <vector>

#include "strut/ident/model.h"
#include "strut/ident/transient_fit.h"
#include "strut/sim/transient.h"

namespace strut::sim {

struct DropFitOptions {
  //! IDA's relative tolerance, for the state and (IDASensEEtolerances) the sensitivities. 1e-7 is
  //! `strut predict drop`'s and the simulated rig's: the integration error (about 1e-8 m of stroke)
  //! stays far below the sensors' noise.
  double rtol = 1e-7;
  //! Sensitivities in IDAS's local error test (IDASetSensErrCon): the steps follow them too.
  bool sensitivity_error_control = true;
  bool IsValid(std::string* error) const;
};

//! Predicts one recorded drop for a fitted model. The rig's fixture mass theta1 is 0 in a drop (the
//! dropped mass moves alone, as in PredictDrop and SimulatedRig::RunDrop), so the drop carries no
//! information on it: its sensitivity is 0. Gravity is theta2 (a known constant): asking for its
//! sensitivity is an error. Not thread-safe (one per experiment).
class DropExperimentPredictor : public ident::TransientExperimentPredictor {
 public:
  //! `model` in any causality (the drop is integrated in its force-input form). Throws
  //! std::invalid_argument for a drop without mass or samples.
  DropExperimentPredictor(const ident::Model& model, const ident::TransientExperimentData& data,
                          DropFitOptions options = {});
  ~DropExperimentPredictor() override;
  DropExperimentPredictor(const DropExperimentPredictor&) = delete;
  DropExperimentPredictor& operator=(const DropExperimentPredictor&) = delete;

  //! The force-input model's outputs (stroke with its sensor zero, pressure, ...) at the record's
  //! times; with `parameters`, d outputs / d theta for them. Throws ident::TransientPredictionError
  //! when the integration fails, std::invalid_argument for bad arguments.
  ident::TransientPrediction Predict(std::span<const double> theta, std::span<const int> parameters) override;

  const ident::Model& model() const { return force_model_; }
  long steps() const { return steps_; }  //!< IDA steps of the last Predict

 private:
  struct Ida;
  ident::Model force_model_, stroke_model_;
  std::vector<double> time_;
  double mass_ = 0.0, impact_velocity_ = 0.0;
  DropFitOptions options_;
  std::unique_ptr<Ida> ida_;
  long steps_ = 0;
};

//! The estimator's factory (ident::EstimatorOptions::transient_predictor) of DropExperimentPredictor.
ident::TransientPredictorFactory DropPredictorFactory(DropFitOptions options = {});

}  // namespace strut::sim
