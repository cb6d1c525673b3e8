// The QC decision (docs/qc.md): a unit's quantities with their sd against the reference's bands,
// decided by the guard-band rule, and the verdict PASS / FAIL / UNDECIDED.
#pragma once

#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "strut/daq/session.h"
#include "strut/ident/session_fit.h"
#include "strut/qc/quantities.h"
#include "strut/qc/reference.h"

namespace strut::qc {

//! The guard band: a quantity conforms only when value +- kGuardBandSigmas sd (its 95 % interval)
//! lies inside [lower, upper]; it is out when that interval lies entirely outside.
inline constexpr double kGuardBandSigmas = 1.96;

enum class Verdict { kPass, kFail, kUndecided };
const char* ToString(Verdict verdict);  //!< "PASS", "FAIL", "UNDECIDED"
//! The exit code of `strut qc`: 0 pass, 1 fail, 2 undecided.
int ExitCodeOf(Verdict verdict);

//! How one quantity stands against its band.
enum class Status {
  kIn,            //!< the 95 % interval lies inside the band
  kOut,           //!< the 95 % interval lies entirely outside the band
  kGuardBand,     //!< the interval straddles a limit: conformance not shown, decided as out (FAIL)
  kUndetermined,  //!< no sd, or the interval is wider than the band: the data cannot decide it
  kUntoleranced,  //!< the reference gives no band: reported only
};
const char* ToString(Status status);  //!< "in", "out", "guard-band", "undetermined", "untoleranced"

struct QuantityDecision {
  Quantity quantity;
  double nominal = NAN, lower = NAN, upper = NAN;
  Status status = Status::kUntoleranced;
  std::string meaning;  //!< in words: "gas under-charged by 9 %", "seal friction 2.1 times nominal"
};

//! One quantity against its band (nullptr: no band).
QuantityDecision DecideQuantity(const Quantity& q, const Band* band);

struct Decision {
  Verdict verdict = Verdict::kUndecided;
  std::vector<std::string> reasons;  //!< why: the quantities out of tolerance, or why undecided
  std::vector<QuantityDecision> quantities;
  std::string serial, session, reference, reference_kind, model;
  std::string fit_verdict;  //!< ident::ToString(FitVerdict), or "" when no fit was made
  std::string fit_verdict_text;
  std::vector<std::string> data_issues;  //!< data defects found in the session
  double seconds = 0.0;                  //!< wall time of the decision (read to verdict)
};

//! Decides from the quantities and the fit's verdict. Not converged, above the noise floor or data
//! defects: UNDECIDED whatever the quantities say (QC never passes data it cannot trust). Otherwise
//! FAIL when a quantity is out or in its guard band, UNDECIDED when one is undetermined (or a band
//! names a quantity the model lacks), PASS when every toleranced quantity is in.
Decision Decide(const std::vector<Quantity>& quantities, const Reference& reference, ident::FitVerdict fit_verdict,
                const std::vector<ident::DataIssue>& issues);

//! The whole QC of one session in memory: prepares the experiments, fits (ident::FitPrepared, the
//! reference's model or "2dof+viscous-damping"), computes the quantities and decides. `fit` (optional)
//! receives the fit. Errors in the data (a missing channel, no periodic experiment) give UNDECIDED
//! with the reason; they do not throw.
Decision RunQc(const daq::Session& session, const std::string& name, const Reference& reference,
               ident::SessionFit* fit = nullptr);
//! The same from a session file (unreadable file: UNDECIDED naming the file and why).
Decision RunQc(const std::string& session_path, const Reference& reference, ident::SessionFit* fit = nullptr);

//! The model QC fits when the reference names none.
inline constexpr const char* kDefaultQcModel = "2dof+viscous-damping";

//! A table for the terminal.
std::string Table(const Decision& decision);

}  // namespace strut::qc
