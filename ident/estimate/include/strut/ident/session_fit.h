// One entry point for a fit from recorded sessions: read, prepare, exclude, choose what to
// estimate, starting values, fit. `strut identify`, `strut discover`, the demo, the benchmarks and
// QC all go through it, so a fit means the same everywhere.
#pragma once

#include <functional>
#include <optional>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "strut/daq/session.h"
#include "strut/ident/estimator.h"
#include "strut/ident/experiment_data.h"
#include "strut/ident/model.h"

namespace strut::ident {

//! The calibration a test lab has, as the relative sd of each transducer's gain: load cell and
//! gas-pressure transducer each known to 0.2 % of reading, the stroke's LVDT to 0.1 % (calibrated
//! against gauge blocks over its range; docs/identification.md, calibration).
inline const std::map<std::string, double> kLabGainSd = {{"force", 0.002}, {"pressure", 0.002}, {"stroke", 0.001}};

//! "force=0.2%,pressure=0.1%" (a value with % is in percent, without it a fraction) or "none" into
//! EstimatorOptions::gain_sd. Throws std::invalid_argument naming the item (an empty item: the
//! text, as --set does).
std::map<std::string, double> ParseGainSd(const std::string& text);
//! Throws std::invalid_argument naming a channel of `gain_sd` that `model` does not have, and its
//! channels: a misspelt transducer would leave its gain out of every interval without a word.
void CheckGainChannels(const std::map<std::string, double>& gain_sd, const Model& model);

struct SessionFitOptions {
  std::string composition = "2dof";
  //! Stroke input by default: the LVDT's noise is far below what the load cell's does to a
  //! force-driven fit (docs/identification.md, causality).
  Causality causality = Causality::kStrokeInput;
  //! "" or "default": every parameter the data can determine (DefaultChoices, then parameters the
  //! data leave undetermined at the start are fixed and named); "paper"; or "theta4,theta6,...".
  std::string estimate;
  std::string params_file;  //!< starting values (and "sd=", "estimate"/"fixed") from a parameter file
  std::string assignments;  //!< "NAME=VALUE,...": starting values over the data's and the file's
  //! Experiments or channels left out: "c" (experiment c), "c:force" (its force channel).
  std::vector<std::string> exclude;
  EstimatorOptions estimator = [] {
    EstimatorOptions o;
    o.gain_sd = kLabGainSd;  // intervals hold the lab's calibration by default
    return o;
  }();
  bool IsValid(std::string* error) const;
};

//! A transducer zero the sessions record (daq::RecordedZeros), and where it came from.
struct SessionZero {
  daq::MeasuredZero zero;
  std::string source;  //!< "S.h5 /calibration stroke_zero"; of several sessions, their weighted mean
};

//! The recorded experiments a fit uses, prepared for one model's causality and grid.
struct FitData {
  std::vector<std::string> sessions;
  std::vector<ExperimentData> experiments;
  //! Drop experiments: fitted beside the periodic ones when the estimator options have a
  //! transient_predictor (strut identify), left out with a warning otherwise.
  std::vector<TransientExperimentData> transients;
  std::vector<DataIssue> issues;  //!< data defects found, and the channels excluded by the user
  std::vector<std::string> excluded;  //!< what --exclude left out, in words
  //! The zeros the sessions record: the starting values and priors of theta39 and theta12. Several
  //! sessions' records of one zero are taken as measurements of it (inverse-variance mean).
  std::optional<SessionZero> load_cell_zero, stroke_zero;
};

//! Reads sessions and prepares their periodic experiments for `model` on the n-point grid, and their
//! drop experiments (PrepareTransientExperiments). Labels
//! that repeat across sessions are prefixed with the file. Throws daq::SessionError or
//! std::invalid_argument naming the file, experiment and channel; an --exclude item that names
//! no experiment or channel is an error too.
FitData ReadFitData(const std::vector<std::string>& sessions, const Model& model, int n,
                    const std::vector<std::string>& exclude = {});

//! The same for a session in memory (simulated, imported); `name` stands for its file in messages.
FitData PrepareFitData(const daq::Session& session, const std::string& name, const Model& model, int n,
                       const std::vector<std::string>& exclude = {});

//! What a fit starts from and what it estimates.
struct FitPlan {
  ParameterSet start;
  ParameterSet data_start;  //!< the starting values from the data alone (a second start: FitPlanned)
  std::vector<std::string> data_sources;  //!< per parameter, where data_start's value came from
  std::vector<ParameterChoice> choices;
  std::vector<std::string> sources;       //!< per parameter: where its starting value came from
  std::vector<std::string> undetermined;  //!< parameters fixed because the data do not determine them, with why
  std::vector<int> undetermined_index;    //!< their positions in `start`, in the same order
  //! Lines for the log: every parameter's starting value as used, its source, estimated or fixed.
  std::vector<std::string> Describe() const;
};

//! Starting values (from the data, then the parameter file, then the assignments) and choices.
//! With the default choices, a parameter whose sd at the start (from the information of all
//! experiments) exceeds its typical size is fixed and named in `undetermined` (an optional term
//! whose effect no experiment reaches, for example).
FitPlan PlanFit(const Model& model, const FitData& data, const SessionFitOptions& options);

//! A parameter the data do not determine: its position and why, in words.
struct Undetermined {
  int index = 0;
  std::string why;
};
//! The estimated parameters of `choices` that the data do not determine at `at`: with the channels'
//! noise floors as their variances, an sd (from the information of all experiments and the priors)
//! beyond the parameter's size. Fixed one at a time, the least determined first, since fixing one
//! can make the others determinable; a parameter with a prior is never fixed. `where` names the
//! point in the reasons ("the start", "the fit").
std::vector<Undetermined> UndeterminedAt(const Model& model, const FitData& data, const EstimatorOptions& estimator,
                                         const ParameterSet& at, const std::vector<ParameterChoice>& choices,
                                         std::string_view where);

struct SessionFit {
  Model model;
  FitData data;
  FitPlan plan;
  FitSummary summary;
};

//! The start of `model`, one catalogue term (`term`) beyond the model of `previous` (a fit of the
//! same data): `previous`'s values and estimated set, the term's own size and shape parameters
//! estimated from where the located mismatch puts them (CandidateStartingValues; under stroke
//! input only), the rest at their defaults. `log` (optional) says where the term's values came from.
struct TermStart {
  ParameterSet start;
  std::vector<ParameterChoice> choices;
  double size_score = NAN;  //!< CandidateStart::size_score (NaN: none, or not under stroke input)
};
TermStart StartWithTerm(const Model& model, const std::string& term, const FitSummary& previous,
                        std::vector<std::string>* log = nullptr);
//! The start of `model` from `previous` (a fit of the same data) alone: its values and estimated set
//! (with their priors) where the two share a parameter, the rest at the defaults and DefaultChoices.
TermStart StartFromFit(const Model& model, const FitSummary& previous);

//! Reads, plans and fits.
SessionFit FitSessions(const std::vector<std::string>& sessions, const SessionFitOptions& options,
                       const std::function<void(const FitProgress&)>& progress = {});
//! Plans and fits already prepared data. When the fit from the plan's start (the user's values
//! over the data's) is not converged or not at the noise floor and the user's values differ from
//! the data's, it is repeated from the data's own starting values (the parameters with a prior keep
//! the user's value, the prior's mean) and the better posterior is kept; the summary says so.
//! When it is still not at the floor and the composition adds catalogue terms to its base (stroke
//! input, the default estimated set), it is fitted once more by continuation, as discovery reaches
//! it: the base from the data's start, then the terms one at a time, each from where the located
//! mismatch puts it (StartWithTerm), the user's values kept; the better posterior is kept.
SessionFit FitPrepared(FitData data, const Model& model, const SessionFitOptions& options,
                   const std::function<void(const FitProgress&)>& progress = {});
//! Fits with a given plan (what FitPrepared does after PlanFit), the second start included: a
//! benchmark restarts a fit from far-off values with the same estimated set this way.
SessionFit FitPlanned(FitData data, const Model& model, FitPlan plan, const SessionFitOptions& options,
                      const std::function<void(const FitProgress&)>& progress = {});

}  // namespace strut::ident
