// Periodic equilibrium states by time discretisation (paper section 2.1, method.md).
//
// One period is cut into n equidistant points with periodic wrap-around; time derivatives become
// difference (or spectral) operators, the model residual on every point gives G(z, theta) = 0,
// solved by Newton with step halving. Output sensitivities d yhat / d theta reuse the last
// Newton factorisation (paper eqs. 14, 15).
#pragma once

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <array>
#include <cmath>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "strut/ident/cyclic_banded.h"
#include "strut/ident/grid.h"
#include "strut/ident/model.h"

namespace strut::ident {

//! No periodic solution was found (no convergence, singular Jacobian, non-finite values).
class PeriodicSolverError : public std::runtime_error {
 public:
  PeriodicSolverError(const std::string& what, double residual_norm, int iterations)
      : std::runtime_error(what), residual_norm(residual_norm), iterations(iterations) {}
  double residual_norm;  //!< scaled residual norm reached
  int iterations;
};

//! One period of the input (force or measured stroke) on the grid t_mu = phase_mu / f.
struct PeriodicInput {
  double frequency = 0.0;      //!< Hz
  std::vector<double> values;  //!< n values
  //! The grid's phases, strictly increasing in [0, 1), when it is not equidistant (empty: mu / n):
  //! a grid that keeps every recorded sample around the velocity reversals and fewer elsewhere.
  std::vector<double> phases;
  double phase(int mu) const {
    return phases.empty() ? static_cast<double>(mu) / static_cast<double>(values.size()) : phases[mu];
  }

  //! mean + amplitude sin(2 pi f t).
  static PeriodicInput Sine(double frequency, double mean, double amplitude, int n);
  //! Period-synchronous average of `periods` whole recorded periods starting at sample 0,
  //! interpolated linearly onto the n grid points. Throws std::invalid_argument on bad sizes.
  static PeriodicInput FromRecord(std::span<const double> samples, double sample_rate, double frequency, long periods,
                                  int n);
};

struct PeriodicSolverOptions {
  Scheme scheme = Scheme::kBackward2;
  int max_iterations = 60;  //!< Newton iterations before giving up
  int max_halvings = 30;    //!< step halvings per iteration before giving up
  //! Converged when every Newton step component is below its unknown's scale (stroke 1e-9 m,
  //! force 1e-6 N, pressure 1e-3 Pa, temperature 1e-6 K) times this factor.
  double tolerance = 1.0;
  //! Cold start: periods of time marching (backward scheme) from the quasi-static guess before
  //! Newton; 0 starts Newton from the quasi-static guess itself.
  int start_up_periods = 2;
  //! Cold start on a coarse grid: the periodic solution on this many points (backward2, from the
  //! quasi-static guess and the start-up march) is interpolated onto the grid and starts Newton
  //! there. Used when n >= 2 coarse_points; 0 never. On the coarse grid the friction switches are
  //! smooth, so its Newton needs few steps, and the fine Newton starts within its quadratic range.
  //! Multisine inputs with harmonics the coarse grid cannot carry want 0.
  int coarse_points = 50;
  //! Jacobian reuse: after a full Newton step whose simplified correction shrank by at least this
  //! factor, the next steps reuse the factorisation (simplified Newton) until the contraction is
  //! slower; a warm start first tries the factorisation it carries. 0: a new Jacobian every step.
  double reuse_contraction = 0.25;
  bool IsValid(std::string* error) const;
};

//! One period of a periodic equilibrium state.
//! The solver's working state carried by a solution for warm starts and sensitivities: not part
//! of the answer, which is the same with or without it.
struct PeriodicSolverState {
  //! The factorised Newton Jacobian the solution was reached with (null for a guess): warm starts
  //! take simplified Newton steps with it, and sensitivities (eq. 14) reuse it when it is current
  //! (`jacobian_contraction` 0).
  std::shared_ptr<const CyclicBandedLU> jacobian;
  //! How far `jacobian` is from the one at the solution. 0: it was factorised for the final Newton
  //! step (at the last iterate but one, a step below the tolerance away), so sensitivities are
  //! exact with it. Else simplified steps carried an older factorisation along, and this is the
  //! contraction of the last one (about the relative error of sensitivities computed with it;
  //! infinite when unknown).
  double jacobian_contraction = INFINITY;
  //! dz/dtheta (unknowns of every point stacked, m n rows) for the parameters at these positions,
  //! when OutputSensitivities computed them: a warm start then begins at the tangent prediction
  //! z + dz/dtheta (theta_new - theta) when only these parameters changed.
  Eigen::MatrixXd unknown_sensitivities;
  std::vector<int> sensitivity_parameters;
};

struct PeriodicSolution {
  Scheme scheme = Scheme::kBackward2;
  double frequency = 0.0;
  int n = 0;
  Eigen::MatrixXd unknowns;           //!< m x n: column mu holds the unknowns at t_mu
  std::vector<std::string> channels;  //!< output channel names
  Eigen::MatrixXd outputs;            //!< channels x n
  PeriodicInput input;
  std::vector<double> theta;          //!< the parameter values it was solved for
  int newton_iterations = 0;    //!< Newton steps on this grid (full and simplified)
  int factorizations = 0;      //!< Jacobians assembled and factorised on this grid
  double residual_norm = 0.0;  //!< max scaled residual at the last iterate evaluated (before the final correction)

  //! What the solver carries from this solve to the next (see PeriodicSolverState). A cache that
  //! OutputSensitivities may replace, so one solution object must not be passed to two such calls
  //! on different threads at once; fit results hold none (FitSummary clears it).
  mutable PeriodicSolverState solver_state;

  std::vector<double> time() const;  //!< t_mu = mu / (n f), s
  //! Row of `outputs` for a channel; std::out_of_range if absent.
  Eigen::VectorXd channel(std::string_view name) const;
};

//! The damper's full dynamic stroke, m (method.md: q = 0 fully extended, 0.264 m fully compressed).
inline constexpr double kDamperStroke = 0.264;
//! How far a solved stroke may leave 0 .. kDamperStroke before it is impossible, m.
inline constexpr double kDamperStrokeMargin = 0.005;

//! The first physically impossible part of a periodic solution of `model` for `theta`, in words
//! (what, its worst value, where in the period and the allowed range), or nullopt when it is
//! possible: absolute gas pressure <= 0, gas temperature <= 0 K, gas volume 1 + theta6 q <= 0, or
//! under force input a stroke q outside -kDamperStrokeMargin .. kDamperStroke + kDamperStrokeMargin
//! (models whose first output is "stroke"). Channels and parameters a model lacks are not checked;
//! non-finite values are violations. Throws std::invalid_argument when the sizes do not fit the model.
std::optional<std::string> PhysicalViolation(const Model& model, const PeriodicSolution& solution,
                                             std::span<const double> theta);

//! What the estimator needs from a way of predicting periodic outputs: the periodic solver, or
//! (for comparison) transient integration to steady state. Failures throw PeriodicSolverError.
class PeriodicPredictor {
 public:
  virtual ~PeriodicPredictor() = default;
  //! Periodic outputs for the input on its grid; `warm_start` (same n) may speed it up.
  virtual PeriodicSolution Solve(const PeriodicInput& input, std::span<const double> theta,
                                 const PeriodicSolution* warm_start = nullptr) = 0;
  //! d outputs / d theta at a solution: one (n x parameters.size()) matrix per output channel, a
  //! column per position in `parameters` in that order (empty: every parameter in model order).
  //! `exact` false allows an approximation within a few percent (steps of an iteration may use it;
  //! uncertainties must not).
  virtual std::vector<Eigen::MatrixXd> OutputSensitivities(const PeriodicSolution& solution,
                                                           std::span<const double> theta,
                                                           std::span<const int> parameters = {},
                                                           bool exact = true) = 0;
  //! Gradients on the input grid of weighted sums of the outputs: `output_weights` holds one n x k
  //! matrix per output channel, and column b of the (n x k) result is d(sum_c w_c(:, b)^T y_c) / du,
  //! u the input's n grid values. The transpose of the outputs' linearisation in the input (an
  //! adjoint): its cost does not grow with the number of input directions it is projected on.
  //! Empty when the predictor cannot.
  virtual Eigen::MatrixXd InputGradients(const PeriodicSolution& solution, std::span<const double> theta,
                                         const std::vector<Eigen::MatrixXd>& output_weights) {
    return {};
  }
  //! d outputs / d input along input `directions` (n x k, each column a grid function added to the
  //! input's values, its rates taken by the scheme as the solver takes the input's): one (n x k)
  //! matrix per output channel. The forward counterpart of InputGradients, a forward solve per
  //! direction. `exact` as in OutputSensitivities. Empty when the predictor cannot.
  virtual std::vector<Eigen::MatrixXd> InputSensitivities(const PeriodicSolution& solution,
                                                          std::span<const double> theta,
                                                          const Eigen::MatrixXd& directions, bool exact = true) {
    return {};
  }
};

//! Solves periodic equilibria of one model; keeps the last factorisation for sensitivities.
class PeriodicSolver : public PeriodicPredictor {
 public:
  PeriodicSolver(Model model, PeriodicSolverOptions options = {});

  const Model& model() const { return model_; }
  const PeriodicSolverOptions& options() const { return options_; }

  //! Periodic solution for the input; from `warm_start` (same n) or from the quasi-static guess.
  //! Throws PeriodicSolverError with the residual reached when Newton fails.
  PeriodicSolution Solve(const PeriodicInput& input, std::span<const double> theta,
                         const PeriodicSolution* warm_start = nullptr) override;

  //! d outputs / d theta at a solution (eqs. 14, 15): one (n x parameters.size()) matrix per channel,
  //! columns in the order of `parameters` (empty: all). Reuses the solution's Newton factorisation
  //! when it is current, else factorises at the solution (and keeps that in it). Not `exact`: also
  //! the factorisation its simplified steps carried when they contracted below 0.05 (the paper's
  //! reuse of the last factorisation; the sensitivities are then within about that fraction).
  std::vector<Eigen::MatrixXd> OutputSensitivities(const PeriodicSolution& solution,
                                                   std::span<const double> theta,
                                                   std::span<const int> parameters = {},
                                                   bool exact = true) override;

  //! Input gradients of weighted outputs (see PeriodicPredictor): one transposed solve with the
  //! Jacobian at the solution (the factorisation of eq. 14) per column of the weights. The input's
  //! rates enter through the scheme's stencil, as the solver applies it.
  Eigen::MatrixXd InputGradients(const PeriodicSolution& solution, std::span<const double> theta,
                                 const std::vector<Eigen::MatrixXd>& output_weights) override;

  //! d outputs / d input along `directions` (see PeriodicPredictor): -dG/du along each direction
  //! (the input, its rate and acceleration through the scheme's stencil) solved with the Jacobian at
  //! the solution (eq. 14's factorisation), mapped through the output equations.
  std::vector<Eigen::MatrixXd> InputSensitivities(const PeriodicSolution& solution, std::span<const double> theta,
                                                  const Eigen::MatrixXd& directions, bool exact = true) override;

  //! The scaled residual G(z) of the discretised equations (m x n), for tests.
  Eigen::MatrixXd Residual(const Eigen::MatrixXd& unknowns, const PeriodicInput& input,
                           std::span<const double> theta) const;

 private:
  struct InputRates;  // the input's time derivatives on the grid
  Eigen::MatrixXd ResidualAt(const Eigen::MatrixXd& z, const PeriodicInput& input, const InputRates& rates,
                             std::span<const double> theta) const;
  //! Assembles dG/dz at z and factorises it; throws PeriodicSolverError when singular.
  std::shared_ptr<const CyclicBandedLU> Factorize(const Eigen::MatrixXd& z, const PeriodicInput& input,
                                                  const InputRates& rates, std::span<const double> theta,
                                                  int iteration, double norm);
  template <class J>
  void AssembleJacobianWith(const Eigen::MatrixXd& z, const PeriodicInput& input, const InputRates& rates,
                            std::span<const double> theta);
  Eigen::MatrixXd ColdStart(const PeriodicInput& input, std::span<const double> theta) const;
  //! Factorises at the solution unless its Jacobian is current (a cache in the solution).
  void MakeJacobianCurrent(const PeriodicSolution& solution, const InputRates& rates, std::span<const double> theta);
  //! -dG/dtheta at a solution for the parameters `wanted` (at most the Jet's directions), scaled like
  //! G (eq. 14's right-hand side), into `rhs` (m n x wanted).
  template <class J>
  void ParameterResiduals(const PeriodicSolution& solution, const InputRates& rates, std::span<const double> theta,
                          const std::vector<int>& wanted, Eigen::Ref<Eigen::MatrixXd> rhs) const;
  //! d outputs / d theta from dz/dtheta (eq. 15) for the parameters `wanted` (at most the Jet's
  //! directions) into columns first_column .. of each channel's (n x all wanted) matrix in `sens`.
  template <class J>
  void OutputDerivatives(const PeriodicSolution& solution, std::span<const double> theta,
                         const std::vector<int>& wanted, const Eigen::Ref<const Eigen::MatrixXd>& dz,
                         std::vector<Eigen::MatrixXd>& sens, int first_column) const;
  //! Moves a warm start's unknowns z along its sensitivities to `theta`; false when it cannot.
  bool TangentPrediction(const PeriodicSolution& from, std::span<const double> theta, Eigen::MatrixXd& z) const;
  //! Damped Newton from z, starting with the factorisation `lu` when given (simplified steps).
  PeriodicSolution Newton(Eigen::MatrixXd z, std::shared_ptr<const CyclicBandedLU> lu, const PeriodicInput& input,
                          const InputRates& rates, std::span<const double> theta);
  struct SolverCounts {
    int iterations = 0;
    int factorizations = 0;
    double residual_norm = 0.0;  //!< max scaled residual at the last iterate evaluated
    double norm = 0.0;           //!< its 2-norm
  };
  //! The solution at the converged unknowns z: outputs evaluated, counts and state attached.
  PeriodicSolution Solution(Eigen::MatrixXd z, const PeriodicInput& input, std::span<const double> theta,
                            const SolverCounts& counts, PeriodicSolverState state) const;
  //! Static equilibrium at every grid point; `march_start`: only where a start-up march reads it
  //! before marching there (the first point and the stencil's reach before it), the rest copies.
  Eigen::MatrixXd QuasiStaticGuess(const PeriodicInput& input, std::span<const double> theta,
                                   bool march_start = false) const;
  Eigen::MatrixXd MarchGuess(Eigen::MatrixXd z, const PeriodicInput& input, std::span<const double> theta,
                             int periods) const;
  //! The stencil and the Jacobian's buffer for the input's grid (its n and phases).
  void Prepare(const PeriodicInput& grid);

  Model model_;
  PeriodicSolverOptions options_;
  Stencil stencil_;
  int prepared_n_ = -1;
  std::vector<double> prepared_phases_;
  //! InputSensitivities' last directions and their rates by the stencil: a fit asks for the same
  //! directions (its input coefficients) at every linearisation.
  Eigen::MatrixXd rated_directions_, direction_first_, direction_second_;
  double direction_frequency_ = 0.0;
  Eigen::VectorXd equation_weight_;  //!< 1 / equation scale, per unknown
  CyclicBlockBanded jacobian_;       //!< assembly buffer
  //! Factorisations to reuse: one no solution holds any more is refactorised in place, which
  //! saves its allocation (hundreds of kB at n = 800).
  std::vector<std::shared_ptr<CyclicBandedLU>> lu_pool_;
};

}  // namespace strut::ident
