// Damper models as compositions of named physics terms ("1dof", "2dof", "1dof+heat-exchange").
//
// Every model is written in residual form on the physical variables of one instant:
//   stroke q (compression-positive, with rate and acceleration), axle force F, and the states the
//   terms declare (gas pressure p, gas temperature T, ...), each with its time derivative.
// One residual per unknown: the force balance  sum(term forces) - F = 0, and one equation per state
// (the gas law for p, the heat balance for T, ...). The causality picks the mechanical unknown:
// force input (the paper's choice: q unknown, F given) or stroke input (F unknown, q given).
// Per grid point the unknowns are [q or F, states...].
#pragma once

#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "strut/ident/autodiff.h"
#include "strut/ident/parameters.h"

namespace strut::ident {

class ModelError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

enum class Causality {
  kForceInput,   //!< measured force drives the model; stroke and states are unknown (paper)
  kStrokeInput,  //!< measured stroke drives the model; force and states are unknown
};
std::string_view ToString(Causality c);
Causality ParseCausality(std::string_view text);  //!< "force" or "stroke"

//! A state a term adds to the model (an unknown at every grid point, with its own equation).
struct StateSpec {
  std::string name;            //!< also the output channel name, e.g. "pressure", "temperature"
  std::string unit;            //!< SI unit
  int derivative_order = 0;    //!< 0: algebraic (gas law), 1: first order (heat balance)
  double typical_value = 0.0;  //!< starting value for the static solve
  double scale = 1.0;          //!< size of a meaningful change, for Newton convergence tests
  double equation_scale = 1.0; //!< size of a meaningful residual of its equation
};

//! Variables of one instant, as the terms see them (time derivatives in real time).
template <typename S>
struct PointVariables {
  S stroke{}, stroke_rate{}, stroke_accel{};
  S force{};
  std::span<const S> states;       //!< in model state order
  std::span<const S> state_rates;  //!< time derivatives of the states
};

//! What the terms read and accumulate while the residual of one instant is formed.
template <typename S>
struct TermContext {
  enum class Phase {
    kGasState,  //!< terms add to gas_volume and gas_amount
    kGasLaw,    //!< the gas-law term writes the pressure residual from them
    kBalance,   //!< terms add forces and write their state equations
  };
  Phase phase = Phase::kGasState;
  const PointVariables<S>* v = nullptr;
  std::span<const S> theta;   //!< parameter values, model order
  S force{};                  //!< sum of all term forces (the balance is force - F)
  S gas_volume{};             //!< gas volume relative to the volume at q = 0
  S gas_amount{};             //!< free gas relative to the amount at charge
  std::span<S> state_residuals;
};

class ModelBuilder;

//! One piece of physics: parameters it uses, states it adds, and its contribution to the residual.
//! A term is pure logic: all values come through the context; it keeps only resolved positions.
class Term {
 public:
  //! Bits of phases(): the TermContext phases a term acts in.
  static constexpr unsigned kGasStatePhase = 1, kGasLawPhase = 2, kBalancePhase = 4;
  virtual ~Term() = default;
  virtual std::string_view name() const = 0;
  //! The phases the term acts in; the model calls Evaluate only in those (a residual evaluation
  //! is a few dozen flops per term, so calls that do nothing would cost as much as the physics).
  virtual unsigned phases() const { return kGasStatePhase | kGasLawPhase | kBalancePhase; }
  //! Declares parameters and states (first pass) ...
  virtual void Declare(ModelBuilder& builder) = 0;
  //! ... then resolves the positions of what it reads (second pass, all terms declared).
  virtual void Bind(const ModelBuilder& builder) = 0;
  //! Adds the term's part at every point of a batch (all in the same phase). One call per batch,
  //! not per point: the term's arithmetic is then inlined in the loop and the call costs nothing.
  virtual void Evaluate(std::span<TermContext<double>> points) const = 0;
  virtual void Evaluate(std::span<TermContext<Jet>> points) const = 0;
  virtual void Evaluate(std::span<TermContext<StateJet>> points) const = 0;
};

//! Implements the Evaluate overloads with the term's `template <class S> void Eval(TermContext<S>&) const`.
#define STRUT_TERM_EVALUATE                                                                     \
  void Evaluate(std::span<TermContext<double>> points) const override {                         \
    for (auto& c : points) Eval(c);                                                             \
  }                                                                                             \
  void Evaluate(std::span<TermContext<::strut::ident::Jet>> points) const override {            \
    for (auto& c : points) Eval(c);                                                             \
  }                                                                                             \
  void Evaluate(std::span<TermContext<::strut::ident::StateJet>> points) const override {       \
    for (auto& c : points) Eval(c);                                                             \
  }

//! Collects what the terms declare and resolves names to positions.
class ModelBuilder {
 public:
  //! Adds a parameter; the same index declared twice must mean the same thing.
  void add_parameter(const ParameterSpec& spec);
  //! Adds a state; returns nothing, positions come from state_position() after all declared.
  void add_state(const StateSpec& spec);
  //! Position of a parameter (by paper index) in the model's parameter vector.
  int parameter_position(int index) const;
  //! Position of a state, or ModelError naming the term that needs it.
  int state_position(std::string_view state, std::string_view needed_by) const;
  bool has_state(std::string_view state) const;
  bool has_term(std::string_view term) const;
  //! Names the two mechanical slots (a base term calls this; damper models keep the defaults
  //! "stroke" [m] and "force" [N]): `displacement` is the unknown under force input and the
  //! measured input under stroke input, `drive` the other way round. Name, unit, typical value
  //! and scale are used; `drive.equation_scale` is the scale of the balance residual. Throws
  //! ModelError when two terms name them differently.
  void declare_channels(const StateSpec& displacement, const StateSpec& drive, std::string_view by);
  //! The parameter (by index) that is the displacement sensor's offset: measured = true + offset.
  void set_output_offset(int index);

 private:
  friend class Model;
  std::vector<ParameterSpec> parameters_;
  std::vector<StateSpec> states_;
  std::vector<std::string> term_names_;
  std::optional<StateSpec> displacement_, drive_;
  std::string channels_by_;
  int output_offset_index_ = -1;
};

//! A composed model with a fixed causality. Cheap to copy (terms are shared, immutable).
//! What is known of each experiment that some terms are a function of (ParameterSpec::experiment_condition).
struct ExperimentConditions {
  double session_time = 0.0;     //!< theta38: 0 the session's first experiment, 1 its last
  double static_position = 0.0;  //!< theta40: m, the experiment's static stroke position
};

class Model {
 public:
  //! Builds "BASE[+term...]" (BASE: 1dof, 2dof, linear-oscillator). Throws ModelError listing
  //! the catalogue.
  static Model Build(std::string_view composition, Causality causality);
  //! Names of the bases and terms that compositions may use.
  static std::vector<std::string> Catalogue();

  //! Canonical composition, e.g. "2dof" for "1dof+heat-exchange+gas-solubility".
  const std::string& composition() const { return composition_; }
  Causality causality() const { return causality_; }
  const std::vector<std::string>& term_names() const { return term_names_; }
  bool has_term(std::string_view name) const;

  //! Parameter specs with default values.
  const ParameterSet& defaults() const { return defaults_; }
  //! `theta` for one experiment: its conditions set where the model has them (theta38 for charge-loss
  //! and the discrepancy's drifts, theta40 for its static functions), the rest as it is.
  std::vector<double> AtExperiment(std::vector<double> theta, const ExperimentConditions& conditions) const;
  int parameter_count() const { return defaults_.size(); }

  //! Unknowns per grid point: [mechanical unknown, states...].
  int unknown_count() const { return 1 + static_cast<int>(states_.size()); }
  const std::vector<StateSpec>& states() const { return states_; }
  //! Highest time derivative of unknown j that the equations use (2 for a free stroke).
  int derivative_order(int j) const;
  //! Name, unit, typical value and scales of unknown j (j = 0: "stroke" or "force").
  StateSpec unknown_spec(int j) const;
  //! Scale of equation j (0: force balance, in N).
  double equation_scale(int j) const;

  //! Output channels: the displacement ("stroke"), the drive ("force"), then every state
  //! ("pressure", "temperature", ...). A generic base names the first two itself ("y", "u").
  std::vector<std::string> output_channels() const;
  //! The channel that drives the model: the drive ("force") under force input, the
  //! displacement ("stroke") under stroke input.
  const std::string& input_channel() const;
  //! The mechanical output channel: the displacement under force input, the drive under stroke input.
  const std::string& mechanical_channel() const;
  //! Unit of an output channel.
  std::string channel_unit(std::string_view channel) const;

  //! Residual of one instant: r has unknown_count() entries.
  //! x, xd, xdd: unknowns and their first and second time derivatives; u, ud, udd: the input
  //! (force or measured stroke) and its time derivatives. All spans have unknown_count() entries
  //! except the input.
  //! The residuals of many instants at once (the periodic solver's grid): x, xd, xdd and r hold
  //! unknown_count() entries per instant one instant after the other, u, ud, udd one each.
  template <typename S>
  void Residuals(std::span<const S> x, std::span<const S> xd, std::span<const S> xdd, std::span<const S> u,
                 std::span<const S> ud, std::span<const S> udd, std::span<const S> theta, std::span<S> r) const;
  template <typename S>
  void Residual(std::span<const S> x, std::span<const S> xd, std::span<const S> xdd, const S& u,
                const S& ud, const S& udd, std::span<const S> theta, std::span<S> r) const;

  //! Output channel values at one instant (order of output_channels()).
  template <typename S>
  void Outputs(std::span<const S> x, const S& u, std::span<const S> theta, std::span<S> y) const;

  //! Static equilibrium (all rates zero) for a constant input. Throws ModelError if Newton fails.
  //! `guess` (unknown_count() values) starts Newton; empty means the typical values.
  std::vector<double> StaticEquilibrium(double input, std::span<const double> theta,
                                        std::span<const double> guess = {}) const;

 private:
  template <typename S, int kBatch>
  void ResidualBatches(std::span<const S> x, std::span<const S> xd, std::span<const S> xdd, std::span<const S> u,
                       std::span<const S> ud, std::span<const S> udd, std::span<const S> theta, std::span<S> r) const;
  template <typename S>
  PointVariables<S> Assemble(std::span<const S> x, std::span<const S> xd, std::span<const S> xdd,
                             const S& u, const S& ud, const S& udd, std::span<const S> theta) const;

  std::string composition_;
  Causality causality_ = Causality::kForceInput;
  std::vector<std::string> term_names_;
  std::vector<std::shared_ptr<const Term>> terms_;
  std::vector<const Term*> phase_terms_[3];  //!< the terms acting in each phase, in evaluation order
  std::vector<StateSpec> states_;
  ParameterSet defaults_;
  StateSpec displacement_, drive_;  //!< the two mechanical slots: stroke and force for dampers
  int stroke_offset_position_ = -1;  //!< output offset (theta12 for dampers) position, -1 if none
  int session_time_position_ = -1;     //!< theta38's position, -1 if none
  int static_position_position_ = -1;  //!< theta40's position, -1 if none
};

}  // namespace strut::ident
