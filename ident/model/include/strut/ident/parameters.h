// Model parameters: paper index (theta1..theta17, further terms from theta18 on), a descriptive
// name, a unit and a default value; and the value sets the commands and the estimator work on.
#pragma once

#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace strut::ident {

//! What a lab knows of its stroke sensor's zero without a calibration against the damper's
//! extension stop: a few millimetres (the default prior on theta12).
inline constexpr double kStrokeZeroPriorSd = 2.0e-3;

//! What a lab knows of its load cell's zero under the fixture's weight: about 100 N for a
//! 100-250 kN cell (damper-physics.md §1.7; the default prior on theta39).
inline constexpr double kLoadCellZeroPriorSd = 100.0;

//! The sensor zeros' parameters: theta12 the stroke reading at full extension, theta39 the load
//! cell's zero. A zero the session records (daq::RecordedZeros) is their prior.
inline constexpr int kStrokeZeroIndex = 12;
inline constexpr int kLoadCellZeroIndex = 39;

//! theta38: when an experiment was recorded, as a fraction of its session (0 the first, 1 the last;
//! daq::ExperimentSessionTimes), the condition a drift over the session (charge-loss) is a function of.
inline constexpr int kSessionTimeIndex = 38;
//! theta40: the experiment's static stroke position (m, as recorded), the condition a level that
//! differs between static-position groups (the empirical discrepancy's static functions) is a function of.
inline constexpr int kStaticPositionIndex = 40;

//! A user mistake in naming or giving parameters (unknown name, bad number, bad file line).
class ParameterError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

//! The physically admissible values of a parameter: an interval whose ends are each open or
//! closed, infinite where physics sets no bound. `--set` and `--params` refuse values outside
//! it; the estimator keeps its iterates inside it.
struct PhysicalRange {
  static constexpr double kInfinity = std::numeric_limits<double>::infinity();
  double lower = -kInfinity;
  double upper = kInfinity;
  bool lower_open = false;  //!< true: `lower` itself is excluded (a mass is > 0)
  bool upper_open = false;

  //! Any value (offsets, positions, fitted coefficients without a sign).
  static constexpr PhysicalRange Any() { return {}; }
  //! (0, inf): masses, areas, pressures, widths.
  static constexpr PhysicalRange Positive() { return {0.0, kInfinity, true, false}; }
  //! [0, inf): dampings, stiffnesses, compliances, effect sizes whose 0 means "absent".
  static constexpr PhysicalRange NonNegative() { return {0.0, kInfinity, false, false}; }
  //! (-inf, 0): theta6 = -A/V0, minus a temperature.
  static constexpr PhysicalRange Negative() { return {-kInfinity, 0.0, false, true}; }

  bool contains(double v) const {
    if (std::isnan(v)) return false;
    const bool above = lower_open ? v > lower : v >= lower;
    const bool below = upper_open ? v < upper : v <= upper;
    return above && below;
  }
  bool bounded() const { return std::isfinite(lower) || std::isfinite(upper); }
  //! "(0, inf)", "[0, inf)", "(-inf, 0)", "(-inf, inf)".
  std::string ToString() const;
};

//! Description of one model parameter.
struct ParameterSpec {
  int index = 0;              //!< paper numbering: 4 means theta4
  std::string name;           //!< descriptive name, e.g. "gas_area"
  std::string unit;           //!< SI unit, e.g. "m^2"
  double default_value = 0.0; //!< physically consistent default (damper-physics.md, lab charge)
  std::string description;    //!< one line for tables and reports
  //! Estimated when the user names no parameters: everything the shaker data can determine (not the
  //! known constants: gravity, the ambient temperature, fixed shapes of optional terms).
  bool estimate_by_default = false;
  double typical = 0.0;              //!< size of a meaningful value (0: |default_value|); scales the estimator
  //! Sizes its term's effect: estimated when discovery adds the term. 0 (or the physical
  //! neutral) means the effect is absent, and the residual is smooth and nearly linear in it
  //! there (a compliance, not a bulk modulus; a gain, not a ratio), so a fit may start at 0.
  bool sizes_term = false;
  //! Shapes its term's effect (where or how wide: an end stop's position, the Stribeck velocity):
  //! estimated with the size when discovery adds the term; meaningless while the size is 0.
  bool shapes_term = false;
  PhysicalRange range;  //!< the physically admissible values (default: any)
  //! sd of the prior the estimator puts on it by default (0: none; mean: the starting value): for
  //! what the data can barely tell apart from other parameters and a lab knows roughly (the
  //! stroke zero).
  double prior_sd = 0.0;
  //! A known condition of each experiment rather than a property of the unit (theta38, when the
  //! experiment was recorded; theta40, its static position): the fit sets it per experiment from the
  //! recording (Model::AtExperiment) and never estimates it.
  bool experiment_condition = false;

  double typical_size() const { return typical > 0 ? typical : std::abs(default_value); }
  //! Estimated when discovery adds the term: its size and shape parameters.
  bool estimated_with_term() const { return sizes_term || shapes_term; }

  std::string key() const { return "theta" + std::to_string(index); }
};

//! The parameters of one model, in model order, with their current values.
class ParameterSet {
 public:
  ParameterSet() = default;
  explicit ParameterSet(std::vector<ParameterSpec> specs);

  int size() const { return static_cast<int>(specs_.size()); }
  const std::vector<ParameterSpec>& specs() const { return specs_; }
  const ParameterSpec& spec(int position) const { return specs_.at(position); }
  const std::vector<double>& values() const { return values_; }
  std::vector<double>& values() { return values_; }
  double value(int position) const { return values_.at(position); }

  //! Position of a parameter given as "theta4", "4" or its descriptive name; nullopt if absent.
  std::optional<int> find(std::string_view key_or_name) const;
  //! Position, or ParameterError that lists the model's parameters.
  int position(std::string_view key_or_name) const;
  //! Position of theta<index>, or -1 when the model has no such parameter.
  int position_of_index(int index) const;

  double get(std::string_view key_or_name) const { return values_[position(key_or_name)]; }
  void set(std::string_view key_or_name, double value) { values_[position(key_or_name)] = value; }

  //! Applies "NAME=VALUE[,NAME=VALUE...]" (the --set option). Throws ParameterError naming the item,
  //! also for a value outside the parameter's physical range, or the text for an empty item
  //! (nothing is changed then).
  void apply_assignments(std::string_view assignments);

  //! Applies a parameter file (format in docs/parameters.md): lines "NAME = VALUE [# comment]";
  //! further keys on the line ("sd=...", "estimate", "fixed") are read by the estimator.
  //! Throws ParameterError naming the file and line, also for a value outside the physical range.
  void apply_file(const std::string& path);

  //! The first value outside its physical range as a message naming the parameter, the value and
  //! the range ("theta4 gas_area = -1 m^2 is outside its physical range (0, inf)"); nullopt when
  //! every value is admissible.
  std::optional<std::string> RangeViolation() const;
  //! Throws ParameterError with RangeViolation() when a value is outside its physical range.
  void Validate() const;

  //! A table "theta4  gas_area  5.000e-03 m^2" for logs.
  std::string table() const;

 private:
  std::vector<ParameterSpec> specs_;
  std::vector<double> values_;
};

//! One line of a parameter file, parsed.
struct ParameterFileEntry {
  std::string name;
  double value = 0.0;
  std::optional<double> prior_sd;   //!< "sd=..." on the line
  std::optional<bool> estimate;     //!< "estimate" or "fixed" on the line
  int line = 0;
};

//! Parses a parameter file. Throws ParameterError naming the file and line.
std::vector<ParameterFileEntry> ReadParameterFile(const std::string& path);

}  // namespace strut::ident
