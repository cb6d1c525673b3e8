// The simulated rig: the truth damper (an ident::Model integrated by TransientSimulator), driven
// by the servo-hydraulic actuator in stroke control or by a dropped mass, read through the
// sensors, paced by the simulation clock. Produces contract-format sessions (session-format.md)
// like a real rig: whole steady-state periods, SI channels with units, gauge pressure.
// docs/simulated-rig.md describes the procedure.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <optional>
#include <random>
#include <string>
#include <string_view>
#include <vector>

#include "strut/daq/session.h"
#include "strut/ident/model.h"
#include "strut/rig/test_matrix.h"
#include "strut/sim/actuator.h"
#include "strut/sim/clock.h"
#include "strut/sim/sensors.h"
#include "strut/sim/transient.h"
#include "strut/sim/truth.h"

namespace strut::sim {

//! Samples as they leave the acquisition, for a consumer that wants them as a rig streams them.
struct SampleBlock {
  std::string experiment;      //!< label
  double start_time = 0.0;     //!< time of the first sample since the experiment began, s
  double sample_rate = 0.0;    //!< Hz
  bool recording = false;      //!< part of the recorded steady-state periods
  std::vector<double> stroke, force, pressure;  //!< readings in SI (pressure as recorded)
};
using SampleSink = std::function<void(const SampleBlock&)>;

//! How one periodic experiment went.
struct PeriodicRunReport {
  std::string label;
  double start_phase = 0.0;       //!< rad, of the set-point at the first simulated sample
  int settle_periods = 0;         //!< periods simulated before the record began
  int periods_simulated = 0;
  bool settled = false;           //!< consecutive periods agreed within the tolerance before recording
  double settle_change = 0.0;     //!< relative change of the last settling period
  double settle_remaining = 0.0;  //!< that change extrapolated over the slowest decay still under way
  double record_change = 0.0;     //!< largest relative change between recorded periods
  bool started_from_periodic_solution = false;  //!< the periodic-solver shortcut worked
  std::string interlock;          //!< why the controller stopped the test (empty: it did not)
  long ida_steps = 0;
  double simulated_seconds = 0.0;
  double wall_seconds = 0.0;
  ActuatorStats actuator;
  //! The record without sensors (rows: stroke as an ideal LVDT reads it, q + theta12; force, N;
  //! absolute pressure, Pa; gas temperature, K, when the model has it; set-point, m), one column
  //! per recorded sample (none when the interlock stopped the test).
  Eigen::MatrixXd clean;
  std::vector<std::string> clean_rows;
};

//! A drop test: a mass meets the fully extended damper at a stroke velocity (method.md §7).
struct DropSpec {
  std::string label = "drop";
  double mass = 350.0;           //!< kg
  double impact_velocity = 0.5;  //!< m/s
  double duration = 30.0;        //!< s recorded from contact
};

struct DropRunReport {
  long ida_steps = 0;
  double wall_seconds = 0.0;
  double peak_stroke = 0.0;  //!< m (true stroke)
  double peak_force = 0.0;   //!< N
  double final_stroke = 0.0; //!< m (true stroke at the end)
  //! Decay time of the gas-temperature excess T - T_amb, fitted from 20 % to 80 % of the record
  //! (s; 0 without heat exchange), and theta15 / (theta16 (1 + theta6 q)) at the mean stroke of
  //! that window.
  double thermal_time_constant_fit = 0.0;
  double thermal_time_constant_model = 0.0;
  TransientResult result;  //!< the clean simulation (force-input model)
};

//! Settings of one run of the rig.
struct RigRunOptions {
  unsigned long seed = 1;  //!< noise, start phases and spikes: the same seed gives the same session
  ClockOptions clock;      //!< fast (default) or paced to the wall clock
  SampleSink sink;         //!< optional consumer of the samples as they are acquired
};

class SimulatedRig {
 public:
  //! Throws TruthError when the truth is invalid.
  explicit SimulatedRig(Truth truth);

  const Truth& truth() const { return truth_; }
  //! The truth damper, stroke input (the measured stroke drives it).
  const ident::Model& model() const { return model_; }
  const std::vector<double>& theta() const { return theta_; }

  //! A whole matrix as a session; `reports` (optional) gets one entry per experiment.
  daq::Session RunMatrix(const rig::MatrixPlan& plan, const RigRunOptions& options = {},
                         std::vector<PeriodicRunReport>* reports = nullptr) const;
  //! One periodic experiment, from the settled periodic-solver state through settling to the
  //! record. `clock` and `sink` may be null/empty. `start_phase` (rad, of the set-point at the
  //! first sample) is drawn from `rng` unless given (a comparison at the same sampling phases).
  //! `session_time`: when it is recorded, as a fraction of the session (theta38 of a unit whose charge
  //! leaks; RunMatrix gives each experiment its place in the plan, daq::OrderSessionTime).
  daq::Experiment RunPeriodic(const rig::MatrixEntry& entry, double sample_rate, long periods, std::mt19937_64& rng,
                              PeriodicRunReport* report = nullptr, SimulationClock* clock = nullptr,
                              const SampleSink& sink = {}, std::optional<double> start_phase = std::nullopt,
                              double session_time = 0.0) const;

  //! A drop test as a session of one experiment.
  daq::Session RunDropSession(const DropSpec& drop, const RigRunOptions& options = {},
                              DropRunReport* report = nullptr) const;
  daq::Experiment RunDrop(const DropSpec& drop, std::mt19937_64& rng, DropRunReport* report = nullptr,
                          SimulationClock* clock = nullptr, const SampleSink& sink = {}) const;

 private:
  daq::Session NewSession() const;

  Truth truth_;
  ident::Model model_;
  std::vector<double> theta_;
};

}  // namespace strut::sim
