// Discovery on drawn units (`strut bench confusion`, sim::DrawUnit) that hold one catalogue effect
// at a drawn size, or none: how often the right term is named first, what else is added, how often
// a unit with nothing missing gets a term anyway (false discoveries), and the size of an effect
// above which discovery names it (docs/discovery.md, "Detection sizes").
#pragma once

#include <cmath>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "strut/daq/session.h"
#include "strut/sim/draw.h"

namespace strut::study {

//! The detection study's sizes: per effect the parameter that sets how strongly the unit shows it,
//! drawn from barely detectable to plain.
struct StudyRange {
  std::string effect;
  int index;  //!< theta index of the size
  double low, high;
  bool log;       //!< log-uniform (else uniform)
  bool via_draw;  //!< the draw itself spreads it (sim::DrawSpreads); no size is requested
  const char* unit;
};
const std::vector<StudyRange>& StudyRanges();
const StudyRange* FindStudyRange(const std::string& effect);  //!< null when the effect has none

//! The smallest measure (size or signal) above which at least 95 % of the units (and at least 10)
//! had the right first term; NaN when there is no such measure. `units`: (measure, right first).
double DetectionSize(std::vector<std::pair<double, bool>> units);

//! A fifth of the units sorted by their measure.
struct MeasureBin {
  double low = 0.0, high = 0.0;  //!< the measures of its first and last unit
  long right = 0, count = 0;     //!< right first terms of its units
};
//! The units sorted by their measure in five bins (empty bins left out).
std::vector<MeasureBin> Bins(std::vector<std::pair<double, bool>> units);

struct ConfusionOptions {
  int units = 10;  //!< per effect
  unsigned long first_seed = 2000;
  std::string base = "2dof";         //!< the units' base physics and the baseline model
  std::vector<std::string> effects;  //!< catalogue effects; "none": units with nothing missing
  bool servo = false;                //!< drive through the servo actuator (else an ideal one)
  bool shipped_calibration = false;  //!< keep the shipped transducers' zero and gain errors
  bool study_sizes = false;          //!< sizes from StudyRanges (else the simulated rig's spreads)
  //! Leave-one-out: each unit's effect is also left out of the catalogue discovery may name
  //! (DiscoverOptions::leave_out), so that only the empirical discrepancy can take it up.
  bool leave_out = false;
  //! Where discovery names explanations that fit alike, run the test that decides on the unit's
  //! simulated rig (its own noise seed) and fit them with it (ident::Decide), as `strut discover --decide`.
  bool decide = false;
};

//! Throws std::invalid_argument naming the effect that the options cannot study: one without a
//! study range under study sizes, or the gas solubility from a base other than 1dof+heat-exchange.
void CheckConfusionEffects(const ConfusionOptions& options);

//! The empirical discrepancy's functions whose shape is the signature of a catalogue term (the
//! leave-one-out study's automatic check of the description: the first function discovery chose of
//! those it kept). A name ending in "<0" or ">0" counts only with its coefficient of that sign (a gas
//! volume shrinking as the pressure rises is a real gas's stiffening, one growing an oil's give).
const std::vector<std::string>& SignatureFunctions(const std::string& term);

//! One unit's discovery.
struct ConfusionUnit {
  std::string effect;
  unsigned long seed = 0;
  std::vector<std::string> found;  //!< the terms discovery added, in order
  bool right_first = false;
  double seconds = 0.0;                 //!< wall time of the discovery
  std::optional<sim::EffectSignal> signal;  //!< how plainly the effect shows (none for "none")
  std::optional<double> size;               //!< the effect's size parameter (study sizes)
  struct FirstRound {
    double delta_bic, cv_ratio;
    std::string verdict;
  };
  std::optional<FirstRound> first_round;  //!< the effect's candidate in discovery's first round
  std::vector<std::string> empirical;     //!< the discrepancy's functions discovery kept, in the library's order
  std::vector<std::string> dependence;    //!< and what it said the missing force depends on
  bool at_floor = false;                  //!< the final fit at the noise floor
  //! Leave-one-out: the first chosen function is one of SignatureFunctions(effect).
  bool described = false;
  //! Explanations discovery named as fitting alike (DiscoveryResult::ambiguities): "kept~rival" each.
  std::vector<std::string> alike;
  //! The effect is the first term, or named among the first term's explanations that fit alike.
  bool truth_named = false;
  //! With ConfusionOptions::decide, where there was a test: the model the data chose with it ("" when
  //! they did not), and whether that is the truth's composition.
  std::optional<std::string> decided;
  bool decided_right = false;
};

//! One effect's row of the table.
struct ConfusionRow {
  std::string effect;
  const StudyRange* study = nullptr;  //!< the size range (study sizes)
  int units = 0;
  int right = 0, extra = 0, none = 0;  //!< right first term; other or more terms; nothing found
  int at_floor = 0, empirical = 0, described = 0;  //!< final fit at the floor; discrepancy used; described as the effect
  int ambiguous = 0, truth_named = 0;  //!< units with explanations named alike; the effect first or among them
  int tested = 0, decided_right = 0;   //!< units whose decisive test ran; of them, decided for the truth
  double median_seconds = 0.0;
  std::map<std::string, int> added;  //!< "a+b" (or "(nothing)"): units
  //! Detection in the signal, in what the baseline leaves of it and in the size parameter; NaN:
  //! not reached (or not measured).
  double detection_signal = NAN, detection_left = NAN, detection_size = NAN;
  std::vector<MeasureBin> by_signal;
};

//! Unit `u` of `effect`'s row (seed first_seed + u), its session into `session` when given: what
//! RunConfusionStudy runs for it, so that a study split into ranges of units (strut batch) gives
//! the same units.
ConfusionUnit RunConfusionUnit(const ConfusionOptions& options, const std::string& effect, int u,
                               daq::Session* session = nullptr);
//! `effect`'s row from its units in unit order (the row RunConfusionStudy gives for them).
ConfusionRow SummariseConfusion(const ConfusionOptions& options, const std::string& effect,
                                const std::vector<ConfusionUnit>& units);

//! A unit as `bench confusion --json` and a batch shard keep it, and back (doubles round-trip).
nlohmann::json ConfusionUnitJson(const ConfusionUnit& unit);
ConfusionUnit ConfusionUnitFromJson(const nlohmann::json& j);
//! A row as `bench confusion --json` writes it.
nlohmann::json ConfusionRowJson(const ConfusionRow& row);

//! The table `strut bench confusion` prints: its heading, one line per row, and the detection
//! lines of the rows with an effect (empty when there is none).
std::string ConfusionHeading(const ConfusionOptions& options);
std::string ConfusionRowLine(const ConfusionRow& row);
std::string ConfusionDetection(const std::vector<ConfusionRow>& rows);

//! Runs the study; `on_unit` (may be empty) sees each unit and its session as it ends. Throws
//! std::invalid_argument for an effect without a study range when `study_sizes`.
std::vector<ConfusionRow> RunConfusionStudy(
    const ConfusionOptions& options,
    const std::function<void(const ConfusionUnit&, const daq::Session&)>& on_unit = {});

}  // namespace strut::study
