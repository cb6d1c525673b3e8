// Drawn units: dampers with realistic manufacturing and physical scatter around a truth (the
// shipped one by default), reproducible from a seed, each checked to run the test matrix
// (docs/simulated-rig.md "Drawn units"; spreads from damper-physics.md §1.2, §1.3, §2).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "strut/rig/test_matrix.h"
#include "strut/sim/truth.h"

namespace strut::sim {

//! How a drawn quantity scatters around the base value x0.
enum class SpreadKind {
  kUniformFactor,     //!< x0 * U[low, high]
  kLogUniformFactor,  //!< x0 * exp(U[ln low, ln high])
  kUniformOffset,     //!< x0 + U[low, high]
  kNormalOffset,      //!< x0 + N(0, sd = low), clipped to x0 +- high
};

//! A number in [0, 1) from 64 random bits (the top 53): portable, where the standard library's
//! distributions are not, so a seed gives the same draw with every compiler.
inline double UnitUniform(std::uint64_t bits) { return static_cast<double>(bits >> 11) * 0x1.0p-53; }

//! One row of the spreads table: a quantity drawn for every unit (or for every unit with the
//! effect, for an effect's size).
struct DrawSpread {
  std::string quantity;   //!< e.g. "gas_area", "compression_ratio", "preload_fraction"
  std::string sets;       //!< the parameters it sets, e.g. "theta4" or "theta5, theta6"
  SpreadKind kind = SpreadKind::kUniformFactor;
  double low = 1.0, high = 1.0;  //!< the range (factors or offsets in SI); kNormalOffset: sd, clip
  std::string applies;    //!< "all", "1dof", "heat-exchange", "2dof" or an effect name
  std::string source;     //!< where the range comes from
};

//! The spreads, in draw order (the order the random numbers are taken in).
const std::vector<DrawSpread>& DrawSpreads();

//! The effects a drawn unit may have beside its base (catalogue terms with a sizing parameter).
const std::vector<std::string>& ExtraEffects();

//! An extra effect of a drawn unit and, optionally, its size (its sizing parameter's value).
struct EffectRequest {
  std::string name;            //!< one of ExtraEffects()
  std::optional<double> size;  //!< SI; nullopt: drawn (real-gas: the base value, N2's constants)
};

//! What to draw.
struct UnitDraw {
  std::string base = "2dof";  //!< "1dof" (polytropic gas), "1dof+heat-exchange" or "2dof"
  std::vector<EffectRequest> effects;
  //! The experiments every unit must run (feasibility rule); the standard matrix by default.
  std::vector<rig::MatrixEntry> matrix = rig::StandardMatrix();
  //! Reject and redraw units that fail the feasibility rule (off only to study the raw spreads).
  bool feasible_only = true;
  int max_attempts = 200;       //!< candidates before giving up (TruthError)
  double drop_mass = 350.0;     //!< kg: the drop test the lab charge is set for (damper-physics.md §1.1)
  //! Throws TruthError naming the item: unknown base or effect, an effect twice, a bad size.
  void Validate() const;
};

//! The feasibility of one unit for a matrix (docs/simulated-rig.md "Feasibility rule").
struct Feasibility {
  bool feasible = true;
  std::string reason;                //!< why not (empty when feasible)
  double compression_ratio = 0.0;    //!< V0 / V(0.264 m)
  double min_stroke = 0.0;           //!< m, shallowest true stroke of the matrix
  double peak_force = 0.0;           //!< N, largest |F| of the periodic steady states checked
  double drop_margin = 0.0;          //!< N, m g - (p0 - p_atm) A - Coulomb friction at p0
  double charge_pressure = 0.0;      //!< Pa abs at full extension and ambient temperature
};

//! Full dynamic stroke, m (method.md).
inline constexpr double kFullStroke = 0.264;
//! Fraction of the actuator's force_limit the periodic peak force may reach (margin for the
//! actuator's tracking error, noise and the grid).
inline constexpr double kForceLimitMargin = 0.9;

//! Checks `unit` against the rule: compression ratio 5..12 at 0.264 m, the matrix's true stroke
//! at least 1 mm inside full extension, the periodic peak force of the deepest experiments below
//! kForceLimitMargin * force_limit; `drop_mass` > 0 also checks the drop (m g above the preload
//! plus friction). Never throws for a physical reason: an unsolvable unit is infeasible.
Feasibility CheckFeasibility(const Truth& unit, const std::vector<rig::MatrixEntry>& matrix, double drop_mass);

//! Draws a unit around `around` (its parameter values, actuator, sensors, acquisition, faults):
//! the same seed gives the same unit. The result records the draw (Truth::drawn) and holds every
//! parameter of its model. Throws TruthError for an invalid spec or when max_attempts candidates
//! all failed the rule.
Truth DrawUnit(const Truth& around, const UnitDraw& spec, std::uint64_t seed);
//! `truth` on a rig with nothing the damper model leaves out: an ideal actuator (the stroke follows
//! the set-point) and perfectly calibrated transducers (no zero or gain errors; the noise and the
//! ADC stay). The studies of the identification method's own figures use it (docs/identification.md).
Truth WithIdealRig(Truth truth);

//! Draws around the shipped default truth.
Truth DrawUnit(const UnitDraw& spec, std::uint64_t seed);

//! How plainly one effect of a unit shows on a matrix, measured in the data rather than in the
//! effect's parameter: the periodic steady states of the unit (set-point stroke as input) against
//! the same unit with the effect's size at its neutral value, in each channel's noise sd (the
//! unit's sensors). The baseline a fit starts from can absorb part of it (docs/discovery.md,
//! "Detection sizes").
struct EffectSignal {
  //! Largest RMS(difference) / noise sd over the experiments and channels (force, pressure).
  double rms = 0.0;
  std::string experiment, channel;  //!< where `rms` is reached
  //! The chi-square the difference adds over every recorded sample: sum over experiments and
  //! channels of (samples recorded) mean(difference^2) / sd^2.
  double chi2 = 0.0;
  //! The largest RMS / noise sd of what is left of the difference after the baseline has absorbed
  //! what it can: the unit's model without the effect, its default estimated parameters (and their
  //! priors) refitted to the difference, linearised at the neutral unit (one Gauss-Newton step
  //! from the truth, the fit's weights). A gas law absorbs most of a real gas, for instance.
  double left_rms = 0.0;
  std::string left_experiment, left_channel;  //!< where `left_rms` is reached
};

//! The signal of `effect` (one of the unit's extra effects, whose sizing parameters are 0 when
//! it is absent) on `matrix`, recorded as the unit's acquisition says (sample rate, periods).
//! Throws TruthError naming the unit's source when it lacks the effect, the effect has no sizing
//! parameter, a channel has no noise, or an experiment has no periodic steady state.
EffectSignal MeasureEffectSignal(const Truth& unit, std::string_view effect, const std::vector<rig::MatrixEntry>& matrix);

}  // namespace strut::sim
