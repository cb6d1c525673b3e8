// Safety of a rig run (docs/rig-run.md, "Safety"), after the practice of commercial servo-hydraulic
// controllers: every detector has an action (indicate, hold, stop, interlock), limits have an upper
// and a lower level and a persistence, and a matrix that would exceed a limit is refused before
// the rig moves. The detectors are pure logic fed by the runner; each is testable alone.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "strut/daq/acquisition.h"
#include "strut/daq/controller.h"
#include "strut/ident/decisive_test.h"
#include "strut/rig/steady_state.h"
#include "strut/rig/test_matrix.h"

namespace strut::ident {
struct FitRecord;
}

namespace strut::rig {

//! A limits file or a matrix the limits refuse. what() names the file and line, or the experiment
//! and the limit.
class SafetyError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

//! What a detector does when it trips, mildest first.
enum class SafetyAction {
  kIndicate,   //!< an event and a warning; the run goes on
  kHold,       //!< ramp out to the static level, end the experiment aborted, pause the run (resumable)
  kStop,       //!< ramp out to the static level, disarm, end the run aborted
  kInterlock,  //!< stop and disarm at once (hydraulics off), end the run aborted
};
std::string_view ToString(SafetyAction action);
std::optional<SafetyAction> SafetyActionFrom(std::string_view text);

//! A two-sided limit on an acquired channel: tripped when `persistence` consecutive samples lie
//! outside [lower, upper].
struct ChannelLimit {
  bool enabled = true;
  double lower = 0.0, upper = 0.0;
  int persistence = 3;
  SafetyAction action = SafetyAction::kInterlock;
};

//! Every detector's levels and actions, and the actuator's capacity for the matrix check.
//! Defaults: docs/rig-run.md; a TOML file (ReadSafetyConfig) overrides any of them per run.
struct SafetyConfig {
  //! m. The lower end leaves the top-out reference room below a stroke zero 5 mm short of nominal
  //! (its search ends at -7 mm, top_out.h).
  ChannelLimit stroke{true, -0.008, 0.270, 3, SafetyAction::kInterlock};
  ChannelLimit force{true, -30.0e3, 55.0e3, 3, SafetyAction::kInterlock};    //!< N
  ChannelLimit pressure{true, -0.1e6, 18.0e6, 3, SafetyAction::kInterlock};  //!< Pa as acquired (gauge)
  struct Following {
    bool enabled = true;
    double max_error = 0.010;  //!< m: |command - stroke| the controller reports
    int persistence = 5;       //!< consecutive status reads
    SafetyAction action = SafetyAction::kStop;
  } following;
  struct UnderPeak {
    bool enabled = true;
    double fraction = 0.8;  //!< reached stroke amplitude / commanded amplitude below this ...
    int cycles = 3;         //!< ... for this many consecutive cycles at full amplitude
    SafetyAction action = SafetyAction::kStop;
  } under_peak;
  struct Stale {
    bool enabled = true;
    std::chrono::milliseconds timeout{500};  //!< no sample arrived for this long (wall clock)
    SafetyAction action = SafetyAction::kStop;
  } stale;
  //! The stream behind its own clock: the newest sample's time on the linear time rule this far
  //! before its frame arrived. A real module that lags is delivering old data; a simulated rig that
  //! lags is computing slower than --speed asks, which the message says.
  struct Lag {
    bool enabled = true;
    //! Wall clock. Unset: 0.5 s for a stream at its recorded rate (a real rig), 3 s for an
    //! accelerated one (a simulated rig, whose own interlocks judge its samples in time).
    std::optional<std::chrono::milliseconds> max_lag;
    SafetyAction action = SafetyAction::kHold;
  } lag;
  struct Heartbeat {
    bool enabled = true;
    //! The controller's heartbeat counter frozen this long: it is not running its loop.
    std::chrono::milliseconds controller_timeout{1000};
    //! The controller's watchdog on our heartbeat (sent every loop of the runner).
    std::chrono::milliseconds watchdog{1000};
    SafetyAction action = SafetyAction::kInterlock;
  } heartbeat;
  //! The actuator and its supply, for the matrix check before the rig moves.
  struct Actuator {
    double max_velocity = 0.5;     //!< m/s
    double piston_area = 4.0e-3;   //!< m^2 (71 mm bore)
    double max_flow = 1.5e-3;      //!< m^3/s of the supply (90 l/min)
  } actuator;
  //! Limits the controller enforces itself with its own interlock (sent with every set-point).
  daq::ControllerLimits controller;

  //! False with a message naming the item when a value is out of range or limits are not ordered.
  bool IsValid(std::string* error) const;
};

//! Reads a limits file (TOML, docs/rig-run.md): sections [stroke], [force], [pressure],
//! [following_error], [under_peak], [stale], [heartbeat], [actuator], [controller]; anything not
//! given keeps its default. Throws SafetyError naming the file, line and key.
SafetyConfig ParseSafetyConfig(std::string_view text, const std::string& source_name);
SafetyConfig ReadSafetyConfig(const std::string& path);

//! A detector that tripped.
struct Trip {
  std::string detector;  //!< "stroke-limit", "force-limit", "pressure-limit", "following-error",
                         //!< "under-peak", "stale-data", "controller-heartbeat", "controller-fault"
  SafetyAction action = SafetyAction::kIndicate;
  std::int64_t monotonic_ns = 0;
  std::string text;  //!< what, the value and the limit, e.g. "stroke 0.2712 m above 0.27 m for 3 samples"
};

//! Distance of the worst value seen lately to each limit, as a fraction of the limit band
//! (1: in the middle of nowhere, 0: at the limit, < 0 beyond): the progress display's margins.
struct Margins {
  double stroke = 1.0, force = 1.0, pressure = 1.0, following = 1.0;
};

//! The run-time detectors. Each detector trips once (latched) until Reset.
class SafetyMonitor {
 public:
  //! `channels` names the channels of the blocks CheckBlock gets, in order: the limited ones
  //! (stroke, force, pressure) are found there once; the others are not checked. Throws
  //! std::invalid_argument when the config is not valid.
  //! `stream_speed`: recorded seconds per second of the stream's clock (RunnerOptions::stream_speed),
  //! for the lag detector's default and its message.
  SafetyMonitor(SafetyConfig config, const std::vector<std::string>& channels, double stream_speed = 1.0);
  const SafetyConfig& config() const { return config_; }

  //! Channel limits over the samples of a block of the channels given at construction, and the
  //! stream's lag behind its clock. Also notes the samples' arrival for the stale-data detector.
  std::vector<Trip> CheckBlock(const daq::AcquiredBlock& block);
  //! Stale data: no sample arrived since `now_ns - timeout` (the clock starts at Arm(now_ns)).
  std::optional<Trip> CheckStale(std::int64_t now_ns);
  //! The controller: latched faults, its heartbeat counter frozen, command minus feedback.
  std::vector<Trip> CheckStatus(const daq::ControllerStatus& status, std::int64_t now_ns);
  //! Under-peak over a whole cycle at full amplitude of a sine of `commanded_amplitude` (m).
  std::optional<Trip> CheckCycle(const CycleSummary& cycle, double commanded_amplitude, std::int64_t now_ns);
  //! A cycle that is not at full amplitude (ramps) breaks the under-peak count.
  void ResetUnderPeak() { under_peak_count_ = 0; }

  //! Starts the time-based detectors (stale data, controller heartbeat) from now_ns.
  void Arm(std::int64_t now_ns);
  //! Unlatches every detector and clears the persistence counters.
  void Reset(std::int64_t now_ns);
  //! Margins over what was seen since the last TakeMargins (then starts over).
  Margins TakeMargins();
  //! The lag limit in force (the configured one, or the default for this stream's speed).
  std::chrono::milliseconds max_lag() const;
  //! The largest lag seen since Reset, ns (0 when the blocks carry no arrival time).
  std::int64_t largest_lag_ns() const { return largest_lag_ns_; }

 private:
  struct LimitState {
    int count = 0;
    bool latched = false;
  };
  // A limited channel of the block layout: its place in a block and its detector.
  struct LimitedChannel {
    std::size_t k;
    const char* detector;
    const char* unit;
    ChannelLimit SafetyConfig::*limit;
    LimitState SafetyMonitor::*state;
    double Margins::*margin;
  };
  std::optional<Trip> CheckLag(const daq::AcquiredBlock& block);
  std::optional<Trip> CheckLimit(const char* detector, const char* unit, const ChannelLimit& limit, LimitState& state,
                                 double value, std::int64_t t);
  SafetyConfig config_;
  std::vector<LimitedChannel> limited_;  // in the blocks' order
  LimitState stroke_, force_, pressure_, following_;
  double stream_speed_ = 1.0;
  bool stale_latched_ = false, heartbeat_latched_ = false, fault_latched_ = false, under_peak_latched_ = false;
  bool lag_latched_ = false;
  std::int64_t last_sample_ns_ = 0;
  std::int64_t largest_lag_ns_ = 0;
  std::optional<std::uint16_t> last_heartbeat_;
  std::int64_t heartbeat_changed_ns_ = 0;
  int under_peak_count_ = 0;
  Margins margins_;
};

//! A periodic response predicted for an experiment (from a fit): extremes of force (N) and of
//! pressure (Pa, absolute as the models give it; NaN when the model has none).
struct PredictedResponse {
  double force_min = 0.0, force_max = 0.0;
  double pressure_min = 0.0, pressure_max = 0.0;
};
using ResponsePredictor = std::function<PredictedResponse(const MatrixEntry&)>;

//! The response of a fitted model to each experiment's sine (ident's periodic solver, stroke
//! input, `points` grid points per period). The fit is read with ident::ReadFitJson under stroke
//! input. A solver failure throws SafetyError naming the experiment.
ResponsePredictor FitPredictor(const ident::FitRecord& fit, int points = 256);

//! Checks the matrix against the limits before the rig moves: stroke range (static +- amplitude
//! within the stroke limit and the controller's), peak velocity 2 pi f A, actuator flow (piston
//! area x velocity), a whole number (>= 16) of samples per period at `sample_rate`, and with a
//! predictor the predicted force and pressure. Returns one message per violation, each naming the
//! experiment, the value and the limit ("" when none); empty when the matrix may run.
std::vector<std::string> CheckMatrix(const std::vector<MatrixEntry>& matrix, const SafetyConfig& config,
                                     double sample_rate, const ResponsePredictor& predictor = {});

//! The tests a decisive test may be chosen from on a rig with these limits: the recorded
//! experiments' frequencies and kDecisiveTestSlowFrequencies (where a whole number of samples a
//! period), their sample rate and noise (ident::TestSpaceOf), a stroke range kDecisiveTestStrokeMargin
//! inside the stroke limits (and the damper's stroke), peak force and pressure inside the limits by
//! kDecisiveTestMargin of their band, a peak rate within the actuator's velocity and flow less that
//! margin, 9 static positions across the range.
ident::TestSpace DecisiveTestSpace(const std::vector<ident::ExperimentData>& recorded, const SafetyConfig& config);
inline constexpr double kDecisiveTestMargin = 0.1;
//! A decisive test as a one-experiment matrix (label and group "decide", its sample rate and periods).
MatrixPlan DecisiveTestPlan(const ident::DecisiveTest& test);
inline constexpr double kDecisiveTestStrokeMargin = 0.002;  //!< m
inline constexpr double kDecisiveTestSlowFrequencies[] = {0.01, 0.02};  //!< Hz

}  // namespace strut::rig
