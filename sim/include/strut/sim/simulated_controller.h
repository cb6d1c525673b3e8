// The simulated rig as a servo controller: a daq::ControllerBackend with a plant. The controller's
// state machine (arm, run, stop, disarm, reset faults; interlock limits, following error, cycles)
// drives the servo actuator in stroke control, which drives the truth damper, read through the
// sensors: the same Truth, ServoActuator, TransientSimulator and SensorChannels as SimulatedRig,
// but one continuous run in simulated time instead of whole experiments. The owner advances
// simulated time (Advance); set-points and commands take effect at the next chunk boundary.
// docs/simulated-rig.md, "The served rig".
#pragma once

#include <cmath>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "strut/daq/controller.h"
#include "strut/sim/actuator.h"
#include "strut/sim/simulated_rig.h"
#include "strut/sim/truth.h"

namespace strut::sim {

//! What the servo loop is told to do from `start` on (simulated seconds), as a pure function of
//! time: the command r(t) of stroke control (LVDT reading, m), or a closed valve.
struct CommandProgram {
  enum class Kind {
    kLocked,  //!< hydraulics off: the valve is closed and the oil holds the piston where it stops
    kMove,    //!< from `from` to `to` at `rate` (m/s), then hold `to`
    kSine,    //!< mean + amplitude envelope(t) sin(2 pi f (t - start)), ramped in and out over whole cycles
  };
  Kind kind = Kind::kLocked;
  double start = 0.0;
  double from = 0.0, to = 0.0, rate = 0.01;  //!< kMove
  double mean = 0.0, amplitude = 0.0, frequency = 0.0;  //!< kSine
  int ramp_cycles = 0;                                   //!< kSine: cycles of ramp in and of ramp out
  double stop_at = INFINITY;  //!< kSine: the ramp out begins here (a cycle boundary); infinity: not asked

  static CommandProgram Locked(double start);
  static CommandProgram Move(double start, double from, double to, double rate);
  static CommandProgram Sine(double start, double mean, double amplitude, double frequency, int ramp_cycles);

  //! r(t), r'(t), r''(t) for t >= start (kLocked: zero, the loop is open).
  InputSample At(double t) const;
  //! The amplitude fraction 0..1 of a sine at t (0 otherwise).
  double Envelope(double t) const;
  //! kMove: when it reaches `to`; kSine: when the ramp out ends (infinity before a stop is asked).
  double End() const;
  //! The first cycle boundary of the sine at or after t (the stop of a sine happens there).
  double NextCycleBoundary(double t) const;
  //! Whole sine cycles completed by t (counting stops at the end of the ramp out).
  std::uint32_t Cycles(double t) const;
};

struct SimulatedControllerOptions {
  //! LVDT reading where the piston rests, locked, before the first arm (m). The damper starts
  //! there in static equilibrium with the gas at ambient temperature. None: on its top-out stop,
  //! where an unloaded strut rests (Truth::TopOutReading); a reading beyond the stop is taken as
  //! the stop too (the piston cannot rest pressed into it).
  std::optional<double> initial_stroke;
  //! Following-error detector: |command - stroke| beyond this latches fault_bits::kFollowingError
  //! and switches the hydraulics off (m); 0 switches it off. 5 mm is about ten times the servo's
  //! tracking error over the standard matrix.
  double following_error_limit = 0.005;
  //! Simulated seconds integrated in one piece (rounded to whole samples at the truth's sample
  //! rate). Set-points and commands take effect at chunk boundaries; the load the actuator feels
  //! is extrapolated over a chunk. 0.05 s is 10 samples at 200 Hz.
  double chunk_seconds = 0.05;
  //! Sensor noise and faults: the same seed and the same commands at the same simulated times give
  //! the same samples.
  unsigned long seed = 1;
  //! False with a message naming the option.
  bool IsValid(std::string* error) const;
};

//! Figures of the plant so far.
struct SimulatedControllerStats {
  double simulated_seconds = 0.0;
  double cpu_seconds = 0.0;  //!< thread CPU time spent in Advance
  long chunks = 0;
  long ida_steps = 0;
  long recomputed_chunks = 0;  //!< chunks computed again because an interlock tripped inside them
  long knotted_chunks = 0;     //!< chunks whose stroke reached the damper through the loop's knots (no polynomial fit)
};

//! The noise-free state of the plant at the end of the last chunk (for tests and logs).
struct PlantSnapshot {
  double time = 0.0;      //!< s
  double stroke = 0.0;    //!< LVDT reading without noise, m (what the loop controls)
  double force = 0.0;     //!< N
  double pressure = 0.0;  //!< absolute, Pa
  double command = 0.0;   //!< m (the stroke when the hydraulics are off)
  bool hydraulics = false;
};

//! ControllerBackend (stroke control only) with the truth damper behind it. Thread-safe: the
//! Modbus server calls Apply/Execute/Status from its thread while the owner calls Advance from
//! another; those calls only take a short lock (the plant is integrated outside it), so the server
//! always answers at once.
//!
//! Behaviour (MTS practice, docs/simulated-rig.md):
//! - disarmed: hydraulics off, the piston locked where it stopped; the command follows the stroke.
//! - arm (needs a set-point, no fault): hydraulics on, the command moves from the stroke to the
//!   static position at static_rate; kRamping while it moves, kAtStatic when there.
//! - run (needs armed and at the static position): the sine starts at the mean, its amplitude
//!   ramped in over ramp_cycles whole cycles (kRamping), then kFullAmplitude; cycles counts whole
//!   cycles from the run.
//! - stop: the ramp out starts at the end of the present cycle (kStopping), over ramp_cycles
//!   cycles, then armed at the static position. Disarm: hydraulics off at once.
//! - interlocks, checked on every sample while the hydraulics are on: the stroke reading outside
//!   the set-point's stroke limits (kStrokeLimit), the force reading outside its force limits or
//!   beyond the truth's actuator force_limit (kForceLimit), |command - stroke| beyond
//!   following_error_limit (kFollowingError). Each latches its bit, switches the hydraulics off at
//!   that sample (the piston holds where it stops) and the state becomes kFaulted until reset.
//! - a new set-point is applied at once when disarmed or faulted, retargets the move when armed,
//!   and is refused while running or stopping unless it changes only the limits; force control is
//!   refused (the simulated servo closes its loop on stroke only).
class SimulatedController final : public daq::ControllerBackend {
 public:
  //! Throws TruthError for an invalid truth, std::invalid_argument for invalid options or a truth
  //! the stream cannot carry (a sensor that is not 16 bits is fine here; CanModule checks that).
  SimulatedController(Truth truth, SimulatedControllerOptions options = {});
  ~SimulatedController() override;
  SimulatedController(const SimulatedController&) = delete;
  SimulatedController& operator=(const SimulatedController&) = delete;

  std::optional<std::string> Apply(const daq::SetPoint& set_point) override;
  std::optional<std::string> Execute(daq::ControllerCommand command) override;
  daq::ControllerStatus Status() override;

  //! Integrates whole chunks while the next chunk ends at or before `to_time` (simulated s) and
  //! hands each chunk's readings to `sink` (outside the lock), in order: one continuous stream at
  //! the truth's sample rate, experiment label "stream", start_time the simulated time of its
  //! first sample. Returns the simulated time reached. Call from one thread at a time. Throws
  //! TransientError when the damper integration fails; the controller then reports a device
  //! fault and Advance does nothing more.
  double Advance(double to_time, const SampleSink& sink = {});

  double time() const;            //!< simulated time reached, s
  double chunk_seconds() const { return chunk_; }
  double sample_rate() const { return rate_; }
  const Truth& truth() const { return truth_; }
  PlantSnapshot plant() const;
  SimulatedControllerStats stats() const;
  //! The program in force (for tests).
  CommandProgram program() const;

 private:
  struct Plant;
  struct Chunk;
  //! A stretch of a chunk (fine-grid indices from..to) and the polynomial the damper sees there
  //! (none: the loop's knots).
  struct StrokePiece {
    long from = 0, to = 0;
    std::optional<ChebyshevSignal> fit;
  };
  static std::vector<StrokePiece> SmoothPieces(const StrokeTrajectory& stroke, double t0, double fine, long fine_count,
                                               Chunk& out);
  //! The damper's stroke, force and pressure on the chunk's fine grid.
  struct DamperChannels;
  static DamperChannels IntegrateDamper(Plant& plant, const StrokeTrajectory& stroke, double t0, long fine_count,
                                        Chunk& out);
  //! Integrates [t0, t0 + chunk) of `plant` under `program`, with the valve closed from
  //! `closed_from`; fills `out`. Touches no shared state.
  void Integrate(Plant& plant, const CommandProgram& program, double closed_from, Chunk& out) const;
  //! The present state with the time-driven transitions up to `t` (lock held).
  void UpdateStateLocked(double t);
  daq::ControllerStatus StatusLocked() const;

  Truth truth_;
  SimulatedControllerOptions options_;
  double rate_ = 0.0, chunk_ = 0.0;
  long chunk_samples_ = 0;
  std::unique_ptr<Plant> plant_;  //!< the owner's thread only (Advance)

  mutable std::mutex mutex_;
  // Under mutex_:
  daq::ControllerState state_ = daq::ControllerState::kDisarmed;
  std::uint16_t fault_word_ = 0;
  std::optional<daq::SetPoint> set_point_;
  CommandProgram program_;
  double boundary_ = 0.0;  //!< where the next chunk starts: commands take effect here
  PlantSnapshot snapshot_;
  double stroke_reading_ = 0.0, force_reading_ = 0.0;
  std::uint32_t cycles_ = 0;
  bool failed_ = false;
  std::string failure_;
  SimulatedControllerStats stats_;
};

}  // namespace strut::sim
