#include "strut/qc/decision.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <stdexcept>


namespace strut::qc {
namespace {

double Relative(double value, double nominal) { return nominal != 0.0 ? value / nominal - 1.0 : NAN; }

//! "9 %" or "2.1 times": how far value is from nominal, in the words a technician uses.
std::string HowFar(double value, double nominal, const char* noun) {
  const double r = Relative(value, nominal);
  if (!std::isfinite(r)) return fmt::format("{} {:.4g}", noun, value);
  if (r >= 0.5) return fmt::format("{} {:.1f} times nominal", noun, value / nominal);
  return fmt::format("{} {:.0f} % {} nominal", noun, std::abs(100 * r), r >= 0 ? "above" : "below");
}

//! What the value means physically; `side` -1 below the band, +1 above, 0 inside.
std::string Meaning(const std::string& name, double value, double nominal, int side) {
  const double r = Relative(value, nominal);
  if (name == "charge_pressure") {
    if (side == 0) return fmt::format("charge within tolerance ({:+.1f} % of nominal)", 100 * r);
    return fmt::format("gas {}-charged by {:.0f} % ({:.3f} MPa against {:.3f} MPa)", side < 0 ? "under" : "over",
                       std::abs(100 * r), value * 1e-6, nominal * 1e-6);
  }
  if (name == "gas_column") {
    if (side == 0) return fmt::format("gas volume within tolerance ({:+.1f} % of nominal)", 100 * r);
    return fmt::format("gas volume {:.0f} % {}: {} (gas column {:.0f} mm against {:.0f} mm)", std::abs(100 * r),
                       side < 0 ? "small" : "large", side < 0 ? "oil overfilled" : "oil low", value * 1e3,
                       nominal * 1e3);
  }
  if (name == "friction") {
    if (side == 0) return fmt::format("seal friction within tolerance ({:+.0f} % of nominal)", 100 * r);
    return HowFar(value, nominal, "seal friction") + (side > 0 ? ": tight, dry or damaged seal" : ": seal missing or worn");
  }
  if (name == "orifice_damping") {
    if (side == 0) return fmt::format("orifice damping within tolerance ({:+.0f} % of nominal)", 100 * r);
    return HowFar(value, nominal, "orifice damping") +
           (side > 0 ? ": orifice obstructed or undersized" : ": orifice oversized or bypassed");
  }
  if (name == "viscous_damping") {
    if (side == 0) return fmt::format("linear (seal) damping within tolerance ({:.0f} N s/m)", value);
    return fmt::format("linear damping {:.0f} N s/m against {:.0f} nominal{}", value, nominal,
                       side > 0 ? ": a leaking or dragging seal" : "");
  }
  if (name == "wall_heat_conductance") {
    if (side == 0) return fmt::format("heat transfer within tolerance ({:+.0f} % of nominal)", 100 * r);
    return HowFar(value, nominal, "heat transfer to the wall") + (side > 0 ? "" : ": gas insulated (foam, no oil mist?)");
  }
  if (name == "stroke_offset") {
    if (side == 0) return fmt::format("stroke zero within tolerance ({:+.1f} mm from nominal)", (value - nominal) * 1e3);
    return fmt::format("stroke transducer zero {:+.1f} mm from nominal: recalibrate the LVDT", (value - nominal) * 1e3);
  }
  if (name == "load_cell_zero") {
    if (side == 0) return fmt::format("load cell zero within tolerance ({:+.0f} N from nominal)", value - nominal);
    return fmt::format("load cell zero {:+.0f} N from nominal: re-zero the load cell", value - nominal);
  }
  return fmt::format("{:.4g} against {:.4g}", value, nominal);
}

// The decision when the session cannot be judged: undecided, with the reason.
Decision Undecided(std::string reason, const Reference& reference) {
  Decision d;
  d.verdict = Verdict::kUndecided;
  d.reasons.push_back(std::move(reason));
  d.reference = reference.source;
  d.reference_kind = reference.kind;
  return d;
}

}  // namespace

const char* ToString(Verdict verdict) {
  switch (verdict) {
    case Verdict::kPass: return "PASS";
    case Verdict::kFail: return "FAIL";
    case Verdict::kUndecided: return "UNDECIDED";
  }
  return "?";
}

int ExitCodeOf(Verdict verdict) {
  switch (verdict) {
    case Verdict::kPass: return 0;
    case Verdict::kFail: return 1;
    case Verdict::kUndecided: return 2;
  }
  return 2;
}

const char* ToString(Status status) {
  switch (status) {
    case Status::kIn: return "in";
    case Status::kOut: return "out";
    case Status::kGuardBand: return "guard-band";
    case Status::kUndetermined: return "undetermined";
    case Status::kUntoleranced: return "untoleranced";
  }
  return "?";
}

QuantityDecision DecideQuantity(const Quantity& q, const Band* band) {
  QuantityDecision d{q};
  if (!band) {
    d.status = Status::kUntoleranced;
    d.meaning = "no band in the reference: reported only";
    return d;
  }
  d.nominal = band->nominal;
  d.lower = band->lower;
  d.upper = band->upper;
  const double half = kGuardBandSigmas * q.sd;
  const double lo = q.value - half, hi = q.value + half;
  if (!std::isfinite(q.value) || !std::isfinite(q.sd)) {
    d.status = Status::kUndetermined;
    d.meaning = "not determined by the data (the fit did not estimate it)";
    return d;
  }
  if (2 * half > band->upper - band->lower) {
    d.status = Status::kUndetermined;
    d.meaning = fmt::format("not determined closely enough: the 95 % interval [{:.4g}, {:.4g}] is wider than the band",
                            lo, hi);
    return d;
  }
  const int side = q.value < band->lower ? -1 : q.value > band->upper ? 1 : 0;
  if (lo >= band->lower && hi <= band->upper) {
    d.status = Status::kIn;
    d.meaning = Meaning(q.name, q.value, band->nominal, 0);
  } else if (hi < band->lower || lo > band->upper) {
    d.status = Status::kOut;
    d.meaning = Meaning(q.name, q.value, band->nominal, side);
  } else {
    d.status = Status::kGuardBand;
    const bool low = lo < band->lower;
    d.meaning = fmt::format("{}; the 95 % interval [{:.4g}, {:.4g}] straddles the {} limit {:.4g}: conformance not "
                            "shown (guard band), decided as out",
                            Meaning(q.name, q.value, band->nominal, low ? -1 : 1), lo, hi, low ? "lower" : "upper",
                            low ? band->lower : band->upper);
  }
  return d;
}

Decision Decide(const std::vector<Quantity>& quantities, const Reference& reference, ident::FitVerdict fit_verdict,
                const std::vector<ident::DataIssue>& issues) {
  Decision d;
  d.reference = reference.source;
  d.reference_kind = reference.kind;
  d.fit_verdict = ident::ToString(fit_verdict);
  for (const Quantity& q : quantities) d.quantities.push_back(DecideQuantity(q, reference.find(q.name)));
  bool out = false, undetermined = false;
  for (const QuantityDecision& q : d.quantities) {
    if (q.status == Status::kOut || q.status == Status::kGuardBand) {
      out = true;
      d.reasons.push_back(q.quantity.name + ": " + q.meaning);
    } else if (q.status == Status::kUndetermined) {
      undetermined = true;
      d.reasons.push_back(q.quantity.name + ": " + q.meaning);
    }
  }
  for (const Band& b : reference.bands) {
    bool found = false;
    for (const Quantity& q : quantities) found = found || q.name == b.name;
    if (!found) {
      undetermined = true;
      d.reasons.push_back(b.name + ": the reference gives a band but the fitted model has no such quantity");
    }
  }
  for (const auto& issue : issues)
    d.data_issues.push_back(fmt::format("experiment '{}', channel '{}': {}: {}", issue.experiment, issue.channel,
                                        issue.kind, issue.detail));
  std::vector<std::string> distrust;
  if (fit_verdict == ident::FitVerdict::kNotConverged) distrust.push_back("the fit did not converge");
  if (fit_verdict == ident::FitVerdict::kAboveNoiseFloor)
    distrust.push_back("the fit is above the noise floor: the model does not explain the data");
  if (!issues.empty()) distrust.push_back(fmt::format("the session has {} data defect(s)", issues.size()));
  if (!distrust.empty()) {
    d.verdict = Verdict::kUndecided;
    for (auto it = distrust.rbegin(); it != distrust.rend(); ++it) d.reasons.insert(d.reasons.begin(), *it);
  } else if (out) {
    d.verdict = Verdict::kFail;
  } else if (undetermined) {
    d.verdict = Verdict::kUndecided;
  } else {
    d.verdict = Verdict::kPass;
  }
  return d;
}

Decision RunQc(const daq::Session& session, const std::string& name, const Reference& reference,
               ident::SessionFit* fit_out) {
  const auto start = std::chrono::steady_clock::now();
  Decision d;
  const std::string model_name = reference.model.empty() ? kDefaultQcModel : reference.model;
  try {
    ident::SessionFitOptions options;
    options.composition = model_name;
    const ident::Model model = ident::Model::Build(model_name, options.causality);
    ident::SessionFit fit =
        ident::FitPrepared(ident::PrepareFitData(session, name, model, options.estimator.n), model, options);
    d = Decide(ComputeQuantities(model, fit.summary), reference, fit.summary.Verdict(), fit.data.issues);
    d.fit_verdict_text = fit.summary.VerdictText();
    if (fit_out) *fit_out = std::move(fit);
  } catch (const ident::EstimationError& e) {  // the session does not fit: undecided, with why
    d = Undecided(name + ": " + e.what(), reference);
  } catch (const ident::PeriodicSolverError& e) {
    d = Undecided(name + ": " + e.what(), reference);
  } catch (const daq::SessionError& e) {  // a channel or experiment the fit needs is not there
    d = Undecided(name + ": " + e.what(), reference);
  } catch (const std::invalid_argument& e) {  // the reference's model, or data the fit cannot take
    d = Undecided(name + ": " + e.what(), reference);
  }
  d.model = model_name;
  d.serial = session.damper_serial;
  d.session = name;
  d.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return d;
}

Decision RunQc(const std::string& session_path, const Reference& reference, ident::SessionFit* fit) {
  daq::Session session;
  try {
    session = daq::ReadSession(session_path);
  } catch (const daq::SessionError& e) {
    Decision d = Undecided(std::string("cannot read the session: ") + e.what(), reference);
    d.session = session_path;
    return d;
  }
  return RunQc(session, session_path, reference, fit);
}

std::string Table(const Decision& d) {
  std::string s = fmt::format("QC {}  serial {}  session {}\nreference {} ({}), model {}, fit {}\n", ToString(d.verdict),
                              d.serial.empty() ? "?" : d.serial, d.session, d.reference, d.reference_kind, d.model,
                              d.fit_verdict.empty() ? "none" : d.fit_verdict);
  s += fmt::format("  {:<22} {:>12} {:>10} {:>12} {:>12} {:>12}  {:<12} {}\n", "quantity", "value", "sd", "nominal",
                   "lower", "upper", "status", "meaning");
  for (const QuantityDecision& q : d.quantities)
    s += fmt::format("  {:<22} {:>12.5g} {:>10.3g} {:>12.5g} {:>12.5g} {:>12.5g}  {:<12} {}\n", q.quantity.name,
                     q.quantity.value, q.quantity.sd, q.nominal, q.lower, q.upper, ToString(q.status), q.meaning);
  if (!d.reasons.empty()) {
    s += "reasons:\n";
    for (const auto& r : d.reasons) s += "  - " + r + "\n";
  }
  for (const auto& i : d.data_issues) s += "data defect: " + i + "\n";
  s += fmt::format("decided in {:.2f} s (guard band: {} sd)\n", d.seconds, kGuardBandSigmas);
  return s;
}

}  // namespace strut::qc
