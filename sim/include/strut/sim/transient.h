// Transient reference integrator: any ident::Model integrated in time with SUNDIALS IDA
// (variable-order BDF for index-1 DAEs), with an exact Jacobian from the model's Jets.
//
// The DAE state is Y = [unknowns x of the model, plus the stroke rate v under force input]:
//   force input:  F = [ Residual(x, xd = (v, states'), xdd = (v', 0...), u),  v - q' ]
//   stroke input: F =   Residual(x, xd = x', xdd = 0, u, u', u'')
// Algebraic components (pressure; the force under stroke input) have id 0 for IDA.
// A drop test replaces the force input u by the Jet expression M (g - q'') (mass-load mode).
// docs/transient.md describes the integrator and how it checks the periodic solver.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "strut/ident/model.h"
#include "strut/ident/periodic.h"

namespace strut::sim {

//! The integration failed (IDA error, non-finite input, step budget, no steady state).
class TransientError : public std::runtime_error {
 public:
  TransientError(const std::string& what, double time, int flag) : std::runtime_error(what), time(time), flag(flag) {}
  double time;  //!< time reached when the failure happened, s
  int flag;     //!< IDA return flag (0 when the failure is not IDA's)
};

//! Value and first two time derivatives of an input at one instant.
struct InputSample {
  double value = 0.0, rate = 0.0, accel = 0.0;
};

//! A force or measured-stroke input u(t) with u'(t), u''(t) (time from the start of the run, s).
class InputSignal {
 public:
  using Function = std::function<InputSample(double t)>;
  InputSignal() = default;
  //! @pre `f` is callable and gives consistent derivatives (IDA relies on them).
  explicit InputSignal(Function f);
  InputSample operator()(double t) const { return f_(t); }
  bool valid() const { return static_cast<bool>(f_); }

  //! u = value, constant.
  static InputSignal Constant(double value);
  //! u = mean + amplitude sin(2 pi f t), exact derivatives (the grid of PeriodicInput::Sine).
  static InputSignal Sine(double frequency, double mean, double amplitude);
  //! Periodic trigonometric interpolant through the n grid values at t_mu = mu / (n f); exact
  //! derivatives of the interpolant. The Nyquist term of even n is halved (real, symmetric).
  //! Throws std::invalid_argument on an empty grid, a non-positive frequency or non-finite values.
  static InputSignal FromPeriodic(const ident::PeriodicInput& input);

 private:
  Function f_;
};

//! Drop test: a mass rests on the damper, the axle force is F = M (g - q'') (force causality).
//! Starts at q = 0 with q' = impact_velocity and the states at their static values at q = 0
//! (T at ambient).
struct DropLoad {
  double mass = 0.0;             //!< M, kg (> 0)
  double impact_velocity = 0.0;  //!< q'(0), m/s (compression-positive)
  double gravity = 9.81;         //!< g, m/s^2
};

//! What drives the model: a prescribed input or a mass load.
using Load = std::variant<InputSignal, DropLoad>;

//! Integrator settings. Tolerances are explicit: atol_j = atol_factor * unknown_spec(j).scale.
struct TransientOptions {
  //! Relative tolerance of IDA's local error test. 1e-9 is a reference-quality default; 1e-6 is
  //! plenty for plots. Below 1e-14 IDA cannot deliver and the options are invalid.
  double rtol = 1e-9;
  //! Absolute tolerances per unknown are this factor times the unknown's scale (stroke 1e-9 m,
  //! force 1e-6 N, pressure 1e-3 Pa, temperature 1e-6 K; the stroke rate uses 1e-9 m/s).
  double atol_factor = 1.0;
  //! Largest internal step, s; 0 lets IDA choose (the default).
  double max_step = 0.0;
  //! Most internal steps in one run (Simulate or PeriodicSteadyState); TransientError beyond.
  long max_steps = 2'000'000;
  //! Highest BDF order, 1..5.
  int max_order = 5;
  bool IsValid(std::string* error) const;
};

//! Starting point of a run.
struct InitialState {
  //! unknown_count() values [mechanical unknown, states...]; empty: the static equilibrium at
  //! the input at t = 0. IDACalcIC corrects the algebraic ones (pressure, force under stroke input).
  std::vector<double> unknowns;
  //! Force input only: q'(0), m/s.
  double stroke_rate = 0.0;
};

//! Samples of one run.
struct TransientResult {
  std::vector<double> time;                //!< output times, s
  std::vector<std::string> unknown_names;  //!< [stroke or force, states...]
  Eigen::MatrixXd unknowns;                //!< m x k, unknowns at the output times
  Eigen::MatrixXd rates;                   //!< m x k, time derivatives (stroke: the state v; algebraic ones: IDA's BDF estimate)
  Eigen::VectorXd input;                   //!< k: u at the output times (drop: M (g - q''))
  std::vector<std::string> channels;       //!< output channel names (Model::output_channels)
  Eigen::MatrixXd outputs;                 //!< channels x k (Model::Outputs)
  long steps = 0;                          //!< IDA internal steps
  long residual_evaluations = 0;
  long jacobian_evaluations = 0;
  double wall_seconds = 0.0;

  //! Row of `outputs` for a channel; std::out_of_range if absent.
  Eigen::VectorXd channel(std::string_view name) const;
};

//! A periodic steady state found by integrating period after period.
struct PeriodicSteadyStateResult {
  //! The last period on the grid t_mu = mu / (n f) (like PeriodicSolver::Solve); scheme,
  //! newton_iterations and residual_norm carry no meaning here.
  ident::PeriodicSolution solution;
  int periods = 0;               //!< periods integrated
  double last_change = 0.0;      //!< max scaled change between the last two periods
  double estimated_error = 0.0;  //!< last_change extrapolated with the observed contraction rate
  long steps = 0;                //!< IDA internal steps
  double wall_seconds = 0.0;
};

//! Settings of PeriodicSteadyState.
struct SteadyStateOptions {
  int periods_max = 200;  //!< TransientError when not converged after this many periods
  //! Converged when the change between consecutive periods, and its extrapolation to infinitely
  //! many periods, are below tol, each unknown measured in
  //! w_j = max(unknown_spec(j).scale, relative_floor * max_mu |x_j|).
  double tol = 1.0;
  double relative_floor = 1e-9;
  bool IsValid(std::string* error) const;
};

//! The DAE F(t, Y, Y') = 0 that IDA integrates; pure logic, exposed for tests and diagnostics.
class DaeSystem {
 public:
  //! @pre theta has model.parameter_count() values; a DropLoad needs a force-input model.
  DaeSystem(ident::Model model, std::vector<double> theta, Load load);

  const ident::Model& model() const { return model_; }
  int size() const { return size_; }                  //!< m, plus 1 under force input
  int unknown_count() const { return m_; }            //!< m
  bool has_stroke_rate() const { return size_ > m_; }  //!< Y[m] is the stroke rate v
  //! True for components whose derivative appears in F (IDA id 1).
  std::vector<bool> differential() const;
  //! Absolute tolerance weights per component (unknown scales; the stroke rate like the stroke).
  Eigen::VectorXd scales() const;

  //! The input u(t) with derivatives; in drop mode M (g - v') with v' from yp.
  InputSample Input(double t, std::span<const double> yp) const;
  //! F(t, Y, Y'), size() values.
  void Residual(double t, std::span<const double> y, std::span<const double> yp, std::span<double> r) const;
  //! dF/dY + cj dF/dY' from the model's Jets (exact).
  Eigen::MatrixXd Jacobian(double t, std::span<const double> y, std::span<const double> yp, double cj) const;

 private:
  template <class S>
  void Evaluate(double t, std::span<const S> y, std::span<const S> yp, std::span<S> r, int directions) const;

  ident::Model model_;
  std::vector<double> theta_;
  Load load_;
  int m_ = 0, size_ = 0;
};

//! Integrates one model in time with IDA. Owns its SUNDIALS context; every run builds and frees
//! its own IDA memory, so a simulator holds no state between runs (but is not thread-safe).
class TransientSimulator {
 public:
  explicit TransientSimulator(ident::Model model, TransientOptions options = {});
  ~TransientSimulator();
  TransientSimulator(TransientSimulator&&) noexcept;
  TransientSimulator& operator=(TransientSimulator&&) noexcept;
  TransientSimulator(const TransientSimulator&) = delete;
  TransientSimulator& operator=(const TransientSimulator&) = delete;

  const ident::Model& model() const { return model_; }
  const TransientOptions& options() const { return options_; }

  //! Integrates from t = 0 and samples at `output_times` (increasing, >= 0; the last is t_end).
  //! Throws std::invalid_argument on bad arguments, TransientError when IDA fails.
  TransientResult Simulate(std::span<const double> theta, const InputSignal& input,
                           std::span<const double> output_times, const InitialState& initial = {}) const;
  //! As above, sampled every 1/output_rate s from 0 to t_end (t_end included).
  TransientResult Simulate(std::span<const double> theta, const InputSignal& input, double t_end,
                           double output_rate, const InitialState& initial = {}) const;
  //! Drop test (mass-load mode). A stroke-input model is integrated in its force-input form.
  TransientResult Simulate(std::span<const double> theta, const DropLoad& load,
                           std::span<const double> output_times) const;
  TransientResult Simulate(std::span<const double> theta, const DropLoad& load, double t_end,
                           double output_rate) const;

  //! Periodic steady state for a periodic input: one IDA run with a stop at every period
  //! boundary; the n grid samples of consecutive periods are compared until they agree.
  //! The input between grid points is the trigonometric interpolant (InputSignal::FromPeriodic).
  PeriodicSteadyStateResult PeriodicSteadyState(std::span<const double> theta, const ident::PeriodicInput& input,
                                                const SteadyStateOptions& steady = {},
                                                const InitialState& initial = {}) const;

 private:
  struct Context;
  TransientResult Run(const ident::Model& model, std::span<const double> theta, const Load& load,
                      std::span<const double> output_times, const InitialState& initial) const;

  ident::Model model_;
  TransientOptions options_;
  std::unique_ptr<Context> context_;
};

//! The state of a drop at contact (TransientSimulator::Simulate with a DropLoad starts from it):
//! q = 0, q' = the impact velocity, the states at rest at full extension (T at ambient), from the
//! stroke-input static equilibrium at the measured stroke of q = 0 (the sensor zero theta12 when
//! the model has one). `unknowns` are the force-input model's, the stroke first.
InitialState DropContactState(const ident::Model& model, std::span<const double> theta, const DropLoad& load);

//! Sample times 0, 1/rate, ... up to t_end (t_end included). Throws std::invalid_argument.
std::vector<double> UniformTimes(double t_end, double rate);

//! Convenience: the transient periodic steady state of `model` (the reference for PeriodicSolver).
PeriodicSteadyStateResult PeriodicSteadyState(const ident::Model& model, std::span<const double> theta,
                                              const ident::PeriodicInput& input, int periods_max = 200,
                                              double tol = 1.0, const TransientOptions& options = {});

}  // namespace strut::sim
