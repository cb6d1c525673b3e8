// The top-out reference (docs/rig-run.md, "The top-out reference"): before the matrix, a slow
// move in stroke control toward full extension until the top-out contact shows in the force,
// which finds where full extension (true stroke q = 0) reads on the stroke transducer: the stroke
// zero a session records in /calibration (daq::RecordedZeros) and identify takes as the prior of
// theta12. Pure logic here (the move's settings and their check against the limits, the online
// contact test, the fit of the zero); the matrix runner drives the move.
#pragma once

#include <limits>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "strut/rig/safety.h"

namespace strut::rig {

//! How the reference moves and when it has found the contact. Stroke values are readings of the
//! stroke transducer (m), as the controller closes its loop on them.
struct TopOutOptions {
  //! The search starts here, reached at the run's static rate: above every stroke zero the
  //! transducer may have (a zero within 5 mm of nominal) with room for the trend before it.
  double from = 0.007;
  //! The search's end, toward full extension: below every zero the transducer may have. A contact
  //! that has not shown by here is not found. Must lie inside the stroke limits.
  double to = -0.007;
  //! m/s of the search. Slow, because the move goes on for the runner's reaction time after the
  //! contact shows (one loop and a set-point: tens of ms on a real rig, about a second of the
  //! damper's time at --speed 50): 0.1 mm/s presses a 2e7 N/m stop 2 kN further there.
  double rate = 1e-4;
  //! The force limit of the move (N): the contact shows when the force falls this far below its
  //! trend over the search so far (top-out pulls the axle into tension), for `persistence` samples
  //! in a row. Each sample's shortfall is the force limit's margin.
  double force_drop = 1000.0;
  int persistence = 3;
  //! The trend needs this much travel of the search before the contact can show (m): the first
  //! part of the move, where the friction turns over and the servo settles, is left out.
  double settle = 5e-4;
  //! The zero is fitted to the samples from this far above the detection down to the deepest one (m).
  double window = 2e-3;
  //! Relative calibration uncertainty of the stroke transducer's gain, entering the zero's sd as
  //! gain_sd x |zero| (the reading at full extension is the transducer's gain times its offset).
  double gain_sd = 1e-3;
  bool IsValid(std::string* error) const;
};

//! The refusals of the reference move under `limits`, one message each ("top-out reference: ..."),
//! as CheckMatrix words them: its stroke range leaves the stroke limit or the controller's, its
//! rate exceeds the actuator's velocity limit, its force limit reaches beyond the force limits'
//! tension side. Empty when it may run.
std::vector<std::string> CheckTopOut(const TopOutOptions& options, const SafetyConfig& limits);

//! The online contact test of the search: a straight-line trend of force against stroke over the
//! samples since `settle` travel, and the shortfall below it.
class TopOutDetector {
 public:
  explicit TopOutDetector(const TopOutOptions& options) : options_(options) {}
  //! One sample of the search. Returns true once the contact shows (latches).
  bool Add(double stroke, double force);
  bool found() const { return found_; }
  //! The stroke where the contact showed (its first sample below the trend), NaN before.
  double stroke_at_contact() const { return contact_stroke_; }
  //! The latest shortfall below the trend over force_drop (0 .. 1 approaches the contact).
  double measure() const { return measure_; }

 private:
  TopOutOptions options_;
  std::optional<double> first_stroke_;
  double n_ = 0, sy_ = 0, sf_ = 0, syy_ = 0, syf_ = 0;
  int below_ = 0;
  bool found_ = false;
  double contact_stroke_ = std::numeric_limits<double>::quiet_NaN();
  double candidate_ = 0.0;
  double measure_ = 0.0;
};

//! The contact fitted to the search's samples. Against time, not against the stroke reading: the
//! reading's noise (30 um on the simulated LVDT) times the stop's stiffness would swamp the force,
//! while the commanded stroke falls at a constant rate. Force = a + b t + c max(0, t - t_c): the
//! trend and the stop meeting at the contact time t_c; the zero is the stroke reading's straight
//! line over the samples before t_c, at t_c.
struct TopOutFit {
  double zero = 0.0;          //!< m, the stroke reading at full extension
  double sd = 0.0;            //!< m: the fit's, the transducer's resolution and its gain uncertainty together
  double fit_sd = 0.0;        //!< m, of the fit alone (the contact time's and the stroke line's)
  double contact_time = 0.0;  //!< s from the first sample
  double stiffness = 0.0;     //!< N/m, of the contact as the samples show it (force rate / stroke rate)
  double stroke_rate = 0.0;   //!< m/s, of the stroke line (negative: toward full extension)
  double residual_rms = 0.0;  //!< N
  long samples = 0;           //!< in the fit
  long in_contact = 0;        //!< of them after the contact time
};

//! Fits the zero to the search's samples (times in s, stroke readings, forces; in time order,
//! down to the deepest): those from `options.window` of stroke above `contact` (the detector's
//! stroke) on. The contact time is the hinge of the profile least squares, its sd from the
//! linearised covariance with the residual variance before and after it apart; `resolution` (m,
//! one count of the stroke channel) and options.gain_sd are added to the zero's sd. Throws
//! std::invalid_argument when the samples cannot give a zero (too few on either side, a force
//! that does not fall faster after the contact), saying why.
TopOutFit FitTopOut(std::span<const double> time, std::span<const double> stroke, std::span<const double> force,
                    double contact, double resolution, const TopOutOptions& options);

}  // namespace strut::rig
