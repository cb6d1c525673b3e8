// Periodic predictions by transient integration, for comparison with the periodic solver: what a
// user without the paper's method would do. The outputs are the periodic steady state reached by
// integrating the model with IDA period after period (TransientSimulator::PeriodicSteadyState);
// the output sensitivities d yhat / d theta come from SUNDIALS IDAS forward sensitivity analysis,
// the state and sensitivity equations integrated together until the sensitivities, too, repeat
// from one period to the next. `strut bench identify` plugs it into the estimator
// (EstimatorOptions::predictor) and times the same fit both ways.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "strut/ident/model.h"
#include "strut/ident/periodic.h"
#include "strut/sim/transient.h"

namespace strut::sim {

struct TransientPredictorOptions {
  //! IDA/IDAS settings, for the state and (same rtol; atol divided by |theta_i|, IDAS's
  //! IDASensEEtolerances) for the sensitivities.
  TransientOptions integrator;
  //! When the state has reached its periodic steady state (change between periods and its
  //! extrapolation with the observed contraction, TransientSimulator::PeriodicSteadyState).
  SteadyStateOptions steady;
  //! The sensitivities have settled when the change of every dY_j/dtheta_i between consecutive
  //! periods, and its extrapolation, are below max(atol_j / |theta_i|, this * max_mu |dY_j/dtheta_i|).
  //! Sensitivities steer Gauss-Newton and give the posterior sd: 1e-6 of their size is plenty.
  double sensitivity_relative_tol = 1e-6;
  //! IDAS's staggered corrector (sensitivities corrected after the state, each step); false: simultaneous.
  bool staggered = true;
  //! Sensitivities in IDAS's local error test (IDASetSensErrCon). Off, the steps follow the state
  //! alone: cheaper, and the sensitivities are still checked for periodicity.
  bool sensitivity_error_control = true;
  bool IsValid(std::string* error) const;
};

//! Work done so far by one predictor.
struct TransientPredictorStats {
  int solves = 0;                  //!< Solve calls that returned a steady state
  long solve_periods = 0;          //!< periods integrated by them
  long solve_steps = 0;            //!< IDA steps
  double solve_seconds = 0.0;
  int sensitivity_runs = 0;        //!< OutputSensitivities calls
  long sensitivity_periods = 0;
  long sensitivity_steps = 0;      //!< IDAS steps (state and sensitivities together)
  double sensitivity_seconds = 0.0;
  TransientPredictorStats& operator+=(const TransientPredictorStats& o);
};

//! A PeriodicPredictor backed by transient integration. One instance per experiment (the
//! estimator's factory makes one each): it keeps the last steady sensitivities as the warm start of
//! the next sensitivity run. Failures of any kind throw ident::PeriodicSolverError.
class TransientPredictor : public ident::PeriodicPredictor {
 public:
  explicit TransientPredictor(ident::Model model, TransientPredictorOptions options = {});
  ~TransientPredictor() override;
  TransientPredictor(const TransientPredictor&) = delete;
  TransientPredictor& operator=(const TransientPredictor&) = delete;

  const ident::Model& model() const { return model_; }
  const TransientPredictorOptions& options() const { return options_; }
  const TransientPredictorStats& stats() const { return stats_; }

  //! The transient periodic steady state on the input's grid, integrated from the state of
  //! `warm_start` at t = 0 (the stroke rate from its grid values) or from the static equilibrium.
  ident::PeriodicSolution Solve(const ident::PeriodicInput& input, std::span<const double> theta,
                                const ident::PeriodicSolution* warm_start = nullptr) override;

  //! d outputs / d theta on the solution's grid: IDAS forward sensitivities integrated with the
  //! state, from the solution's state at t = 0 (and the last steady sensitivities when there are
  //! some), until the sensitivities are periodic too.
  //! `parameters` (positions; empty: all) are the ones differentiated: each costs one more DAE, so
  //! the estimator names the ones it estimates.
  std::vector<Eigen::MatrixXd> OutputSensitivities(const ident::PeriodicSolution& solution,
                                                   std::span<const double> theta,
                                                   std::span<const int> parameters = {},
                                                   bool exact = true) override;

 private:
  struct Ida;
  ident::Model model_;
  TransientPredictorOptions options_;
  TransientSimulator simulator_;
  std::unique_ptr<Ida> ida_;
  TransientPredictorStats stats_;
  //! Steady sensitivities dY/dtheta at t = 0 (DaeSystem size x parameters) of the last run, and the
  //! input frequency they belong to.
  Eigen::MatrixXd sensitivity_start_;
  double sensitivity_frequency_ = 0.0;
};

//! The sensitivity residuals of the DAE of DaeSystem (`load` an input, not a drop):
//! column k = dF/dY s_k + dF/dY' s'_k + dF/dtheta_{parameters[k]}, from one Jet evaluation; and,
//! in `values` when given, F itself (the tests compare it with DaeSystem::Residual).
Eigen::MatrixXd SensitivityResiduals(const ident::Model& model, std::span<const double> theta, const InputSignal& input,
                                     std::span<const int> parameters, double t, std::span<const double> y,
                                     std::span<const double> yp, const Eigen::MatrixXd& s, const Eigen::MatrixXd& sp,
                                     Eigen::VectorXd* values = nullptr);
//! The same for any load: in mass-load mode (a drop, force-input model) the force is the Jet
//! expression M (g - v') of Y', as DaeSystem writes it, so its sensitivity carries -M s'_v.
Eigen::MatrixXd SensitivityResiduals(const ident::Model& model, std::span<const double> theta, const Load& load,
                                     std::span<const int> parameters, double t, std::span<const double> y,
                                     std::span<const double> yp, const Eigen::MatrixXd& s, const Eigen::MatrixXd& sp,
                                     Eigen::VectorXd* values = nullptr);

}  // namespace strut::sim
