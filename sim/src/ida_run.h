// One SUNDIALS IDAS run over a DaeSystem, optionally with forward sensitivities: the plumbing the
// transient simulator and the transient predictor share (internal to sim/).
#pragma once

#include <idas/idas.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

#include <Eigen/Dense>
#include <cmath>
#include <exception>
#include <span>
#include <string>
#include <vector>

#include "strut/sim/transient.h"

namespace strut::sim::detail {

//! A SUNDIALS context: one per simulator or predictor (they are not thread-safe).
struct SundialsContext {
  SUNContext ctx = nullptr;
  SundialsContext();
  ~SundialsContext();
  SundialsContext(const SundialsContext&) = delete;
  SundialsContext& operator=(const SundialsContext&) = delete;
};

//! Forward sensitivities dY/dtheta_k of the DAE for the parameters at `parameters`, their residuals
//! exact from the model's Jets (SensitivityResiduals).
struct SensitivitySetup {
  const Load* load = nullptr;  //!< the DaeSystem's input or drop load
  std::span<const double> theta;
  std::span<const int> parameters;
  Eigen::MatrixXd start;     //!< dY/dtheta at t = 0: DaeSystem size x parameters
  std::vector<double> pbar;  //!< per parameter, the scale of its sensitivity tolerances
  bool staggered = true;     //!< IDA_STAGGERED, else IDA_SIMULTANEOUS
  bool error_control = false;  //!< sensitivities in the local error test
};

//! What the C callbacks need; they must not throw through IDAS.
struct CallbackData {
  const DaeSystem* system = nullptr;
  const SensitivitySetup* sensitivities = nullptr;
  std::string failure;      //!< why a callback returned an unrecoverable error
  std::exception_ptr error;  //!< what a callback threw (its system's or input's own error)
  std::string ida_message;  //!< the last message of IDAS's error handler
};

//! One run: memory, vectors, dense matrix and solver, freed together. Failures throw TransientError
//! ("transient: <what> failed at t = ... with <IDA flag>: <why>").
class IdaRun {
 public:
  //! Y and a Y' guess at t = 0 (ConsistentStart completes them); `sensitivities` (kept by
  //! reference for the run) adds forward sensitivities.
  IdaRun(SUNContext ctx, const DaeSystem& system, const TransientOptions& options, std::span<const double> y0,
         std::span<const double> yp0, const SensitivitySetup* sensitivities = nullptr);
  ~IdaRun();
  IdaRun(const IdaRun&) = delete;
  IdaRun& operator=(const IdaRun&) = delete;

  //! Algebraic components and all derivatives consistent with the differential ones (IDACalcIC),
  //! and the sensitivities' likewise.
  void ConsistentStart(double tout1);
  //! Integrates to `tout` without passing `tstop` (>= tout); y(), yp() and s() then hold the
  //! solution there.
  void AdvanceTo(double tout, double tstop);

  std::span<const double> y() const { return {N_VGetArrayPointer(y_), static_cast<std::size_t>(n_)}; }
  std::span<const double> yp() const { return {N_VGetArrayPointer(yp_), static_cast<std::size_t>(n_)}; }
  double s(int j, int k) const { return NV_Ith_S(ys_[k], j); }  //!< dY_j/dtheta_k
  double time() const { return t_; }
  long steps() const { return Counter(IDAGetNumSteps); }
  long residual_evaluations() const { return Counter(IDAGetNumResEvals); }
  long jacobian_evaluations() const { return Counter(IDAGetNumJacEvals); }

 private:
  long Counter(int (*get)(void*, long*)) const;
  void Check(int flag, const char* what);
  [[noreturn]] void BudgetExceeded() const;
  [[noreturn]] void Fail(int flag, const std::string& what);

  int n_, ns_ = 0;
  long max_steps_;
  CallbackData data_;
  N_Vector y_ = nullptr, yp_ = nullptr, id_ = nullptr, atol_ = nullptr;
  N_Vector* ys_ = nullptr;
  N_Vector* yps_ = nullptr;
  SUNMatrix matrix_ = nullptr;
  SUNLinearSolver solver_ = nullptr;
  void* mem_ = nullptr;
  double t_ = 0.0;
  double tstop_ = NAN;
};

//! The change of one period's samples (rows: unknowns, columns: grid times) from the previous
//! period's, each row in the larger of its `scale` and `relative_floor` times its peak: what the
//! simulator's and the predictor's periodic steady states converge in.
double PeriodChange(const Eigen::MatrixXd& current, const Eigen::MatrixXd& previous, const Eigen::VectorXd& scale,
                    double relative_floor);

//! The period changes seen so far and when they are small enough. The slowest mode decays
//! geometrically, d_k = rho d_{k-1}, so what is left after a period is d_k rho / (1 - rho). rho comes
//! from the last few periods (one ratio is too noisy once the changes approach the integration
//! error); rho >= 1 means the changes no longer shrink, and d_k itself is the estimate.
class PeriodConvergence {
 public:
  //! Adds one period's change; true once it and what is left after it are within `tol`.
  bool Add(double change, double tol);
  double change() const { return change_; }      //!< the last change (infinity before the first)
  double estimate() const { return estimate_; }  //!< what is left after it

 private:
  std::vector<double> changes_;
  double change_ = INFINITY, estimate_ = INFINITY;
};

}  // namespace strut::sim::detail
