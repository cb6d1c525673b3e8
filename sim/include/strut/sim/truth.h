// The truth of the simulated rig: which physics the simulated damper has (effects), its parameter
// values, and the rig around it (actuator, sensors, acquisition, injected faults). Read from a TOML
// truth file (format in docs/simulated-rig.md); the shipped default sim/data/f16-nose-lab.toml
// is compiled in (DefaultTruth()).
#pragma once

#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "strut/ident/model.h"
#include "strut/sim/actuator.h"
#include "strut/sim/sensors.h"

namespace strut::sim {

//! A mistake in a truth or matrix file; what() names the file and the key or line.
class TruthError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

//! How experiments are sampled and settled.
struct AcquisitionOptions {
  //! Sample rate of periodic experiments, Hz; every matrix frequency must give whole samples per
  //! period (200 Hz does for the standard matrix).
  double sample_rate = 200.0;
  //! Sample rate of drop experiments, Hz.
  double drop_sample_rate = 1000.0;
  //! Whole steady-state periods recorded per periodic experiment.
  long periods = 3;
  //! Settled when two consecutive periods differ by less than this, relative to the range of the
  //! force and of the pressure over the period (each sample compared), and so does that change
  //! extrapolated over the slowest decay still under way (rho / (1 - rho), rho from the last changes).
  double settle_tolerance = 1e-4;
  //! Periods simulated before giving up on settling (the record is then taken anyway and the
  //! experiment says so in its attributes and the log).
  int settle_periods_max = 40;
  //! Record gauge pressure (as most transducers read) rather than absolute.
  bool gauge_pressure = true;
  //! Relative tolerance of the IDA integration of the damper.
  double rtol = 1e-7;
  bool IsValid(std::string* error) const;
};

//! The metal top-out stop every simulated unit has at full extension (true stroke q = 0), outside
//! the identification model: the plant adds its force k max(0, -q) (1 + dissipation max(0, -q'))
//! toward compression to the damper's, so it is exactly nothing while q >= 0 (the matrix stays 1 mm
//! inside, draw.h). What a top-out reference (rig/top_out.h) finds; the served rig's plant has it
//! (SimulatedController), the whole-experiment SimulatedRig needs none. Truth file: [top_out].
struct TopOutContact {
  //! N/m. 2e7: a metal stop (5e7, damper-physics.md §2.9) behind a thin pad; 0: no stop (a rig
  //! whose top-out never shows, for tests).
  double stiffness = 2.0e7;
  double dissipation = 2.0;  //!< s/m, Hunt-Crossley damping over the stiffness
  bool IsValid(std::string* error) const;
};

//! The size of one extra effect of a drawn unit: the value of its sizing parameter.
struct EffectSize {
  std::string effect;     //!< e.g. "viscous-damping"
  std::string parameter;  //!< its sizing parameter's key, e.g. "theta18"
  double size = 0.0;      //!< the value, SI (e.g. 200 N s/m)
  bool given = false;     //!< given by the caller (true) or drawn (false)
};

//! How a drawn unit was drawn (sim/draw.h, docs/simulated-rig.md "Drawn units"); recorded in
//! every session the rig produces from it.
struct DrawRecord {
  std::uint64_t seed = 0;
  std::string base;                 //!< "1dof", "1dof+heat-exchange" or "2dof"
  std::vector<EffectSize> effects;  //!< the extra effects, in EffectNames() order
  std::string around;               //!< source of the truth the unit was drawn around
  int attempts = 1;                 //!< candidates drawn until one passed the feasibility rule
};

//! Everything the simulated rig needs to know about the world it simulates.
struct Truth {
  std::string source = "<built-in default>";  //!< file it came from, for messages
  std::string damper_serial = "SIM-F16N-0001";
  std::string rig = "strut simulated rig";
  std::vector<std::string> effects;  //!< effects switched on, in EffectNames() order
  //! Parameter values as given (name or thetaN, value), applied over the model defaults in order.
  std::vector<std::pair<std::string, double>> parameters;
  ActuatorOptions actuator;
  SensorSet sensors;
  AcquisitionOptions acquisition;
  std::vector<FaultSpec> faults;
  TopOutContact top_out;
  //! Set when the unit was drawn (DrawUnit) rather than read from a file.
  std::optional<DrawRecord> drawn;

  //! Names of the switchable effects (the names of the identification model terms):
  //! heat-exchange, gas-solubility, oil-compressibility, viscous-damping, stribeck-friction,
  //! end-stop, real-gas.
  static const std::vector<std::string>& EffectNames();
  bool has_effect(std::string_view name) const;
  //! The model composition: 2dof when heat-exchange and gas-solubility are on, 1dof+heat-exchange
  //! with heat-exchange alone, 1dof (polytropic gas) without it; plus the other effects.
  std::string Composition() const;
  ident::Model BuildModel(ident::Causality causality) const;
  //! The model's defaults with this truth's values applied. Throws TruthError for a value the
  //! model cannot take.
  ident::ParameterSet Parameters(const ident::Model& model) const;
  //! What a fit of this unit's recorded channels should find: Parameters, and the load-cell zero
  //! theta39 at the force sensor's offset (the plant itself feels no zero; the sensor adds it).
  ident::ParameterSet RecordedParameters(const ident::Model& model) const;
  //! The stroke reading at full extension (q = 0): the LVDT's reading of theta12 through its own
  //! gain and zero errors, what a top-out reference must find. Throws TruthError as Parameters.
  double TopOutReading() const;
  //! Throws TruthError naming `source` when a setting is invalid.
  void Validate() const;
};

//! Reads a truth file. Throws TruthError naming the file and the line or key of every mistake:
//! TOML syntax, unknown table or key, unknown effect or parameter, a value that is not a number.
Truth ReadTruthFile(const std::string& path);
//! Parses truth-file text; `source_name` names it in messages.
Truth ParseTruth(std::string_view text, const std::string& source_name);
//! The shipped default (sim/data/f16-nose-lab.toml, compiled in).
Truth DefaultTruth();
std::string_view DefaultTruthText();

}  // namespace strut::sim
