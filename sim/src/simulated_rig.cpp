#include "strut/sim/simulated_rig.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fmt/format.h>
#include <functional>
#include <memory>
#include <numbers>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "strut/ident/periodic.h"
#include "rig_acquisition.h"
#include "strut/sim/recorded_truth.h"

namespace strut::sim {
namespace {

using Clock = std::chrono::steady_clock;
constexpr double kTwoPi = 2.0 * std::numbers::pi;
// Grid of the periodic solves that give the starting state (central4: about 1e-7 of the range).
constexpr int kStartGrid = 1000;
// The damper's output is taken at least this often to feed the load back to the actuator, Hz.
constexpr double kLoadRate = 1000.0;
// The actual stroke keeps its harmonics down to this amplitude (m), at most this many.
constexpr double kStrokeHarmonicFloor = 1e-10;
constexpr int kMaxStrokeHarmonics = 2000;
// Settling periods in which the damper restarts from the periodic solution for the actual stroke.
constexpr int kRestartPeriods = 3;
// Streamed blocks are at most this long, s.
constexpr double kBlockSeconds = 0.1;

double Range(const Eigen::VectorXd& v) { return v.maxCoeff() - v.minCoeff(); }

//! Largest change between two blocks of a channel, relative to the channel's range.
double RelativeChange(const Eigen::VectorXd& now, const Eigen::VectorXd& before) {
  const double range = std::max(Range(now), 1e-12 * std::max(1.0, now.cwiseAbs().maxCoeff()));
  return (now - before).cwiseAbs().maxCoeff() / range;
}

std::string Format(double v) { return fmt::format("{:.6g}", v); }

//! Streams a block in pieces of at most kBlockSeconds, each when the clock says it is due.
void Emit(const SampleSink& sink, SimulationClock* clock, SampleBlock block, double run_time_of_first) {
  if (!sink && !clock) return;
  const std::size_t count = block.stroke.size();
  const std::size_t piece = std::max<std::size_t>(1, static_cast<std::size_t>(kBlockSeconds * block.sample_rate));
  for (std::size_t i = 0; i < count; i += piece) {
    const std::size_t n = std::min(piece, count - i);
    const double end_time = run_time_of_first + static_cast<double>(i + n) / block.sample_rate;
    if (clock) clock->WaitUntil(end_time);
    if (!sink) continue;
    SampleBlock part;
    part.experiment = block.experiment;
    part.start_time = block.start_time + static_cast<double>(i) / block.sample_rate;
    part.sample_rate = block.sample_rate;
    part.recording = block.recording;
    part.stroke.assign(block.stroke.begin() + i, block.stroke.begin() + i + n);
    part.force.assign(block.force.begin() + i, block.force.begin() + i + n);
    part.pressure.assign(block.pressure.begin() + i, block.pressure.begin() + i + n);
    sink(part);
  }
}

//! The stroke over one period as the periodic solver's input on its start grid.
ident::PeriodicInput StartGridInput(double frequency, const LvdtInverse& model_input,
                                    const std::function<InputSample(double)>& stroke) {
  const double period = 1.0 / frequency;
  ident::PeriodicInput in{frequency, std::vector<double>(kStartGrid)};
  for (int mu = 0; mu < kStartGrid; ++mu) in.values[mu] = model_input(stroke(mu * period / kStartGrid)).value;
  return in;
}

//! Where a periodic experiment starts: the actuator settled against the damper's load, its
//! first period of actual stroke, and the damper's state at the start of that period.
struct PeriodicStart {
  PeriodicLoad load = PeriodicLoad::Constant(0.0);
  std::optional<ident::PeriodicSolution> at_set_point;  //!< the periodic solution at the set-point
  ServoActuator::State actuator;
  StrokeTrajectory trajectory;
  InitialState initial;
};

//! 1. The periodic steady state at the set-point gives the load for settling the actuator; 2. the
//! periodic steady state for the actual stroke of the settled actuator is the damper's start.
//! Both are shortcuts: a real rig would run the sine for minutes until the gas temperature
//! settles. Without a periodic solution the damper settles from its static state.
PeriodicStart StartFromPeriodicSolutions(const std::string& label, const SineSetPoint& set_point,
                                         const LvdtInverse& model_input, const ServoActuator& actuator,
                                         ident::PeriodicSolver& solver, std::span<const double> theta,
                                         PeriodicRunReport& report) {
  const double f = set_point.frequency, period = 1.0 / f;
  PeriodicStart s;
  try {
    s.at_set_point = solver.Solve(StartGridInput(f, model_input, [&](double t) { return set_point.At(t); }), theta);
    const Eigen::VectorXd force = s.at_set_point->channel("force");
    s.load = PeriodicLoad::FromGrid(std::span<const double>(force.data(), force.size()), period);
  } catch (const ident::PeriodicSolverError& e) {
    spdlog::warn("experiment '{}': no periodic solution at the set-point ({}); settling from the static state", label,
                 e.what());
  }
  s.actuator = actuator.SettledState(set_point, s.load, 0.0, std::max(period, 0.5));
  s.trajectory = actuator.Run(set_point, s.load, 0.0, period, s.actuator, &report.actuator);
  if (s.at_set_point) {
    try {
      const ident::PeriodicSolution actual = solver.Solve(
          StartGridInput(f, model_input, [&](double t) { return s.trajectory.At(t); }), theta, &*s.at_set_point);
      s.initial.unknowns.assign(actual.unknowns.col(0).data(), actual.unknowns.col(0).data() + actual.unknowns.rows());
      report.started_from_periodic_solution = true;
    } catch (const ident::PeriodicSolverError& e) {
      spdlog::warn("experiment '{}': no periodic solution for the actual stroke ({}); settling from the static state",
                   label, e.what());
    }
  }
  return s;
}

//! The damper's state at the start of the period from `t0` from the periodic solution for that
//! period's actual stroke (warm-started from the last one, or `first`): its slow thermal mode (a
//! minute deep in the stroke) then starts settled instead of decaying from the first guess. Keeps
//! `initial` where the last period ended when the solver fails.
void RestartFromPeriodicSolution(ident::PeriodicSolver& solver, std::span<const double> theta,
                                 const LvdtInverse& model_input, const SineSetPoint& set_point,
                                 const StrokeTrajectory& trajectory, double t0, const ident::PeriodicSolution& first,
                                 std::optional<ident::PeriodicSolution>& restart, InitialState& initial) {
  try {
    restart = solver.Solve(
        StartGridInput(set_point.frequency, model_input, [&](double t) { return trajectory.At(t0 + t); }), theta,
        restart ? &*restart : &first);
    initial.unknowns.assign(restart->unknowns.col(0).data(), restart->unknowns.col(0).data() + restart->unknowns.rows());
  } catch (const ident::PeriodicSolverError&) {
    // keep integrating from where the last period ended
  }
}

//! What the damper sees over the period from `t0`: the actual stroke as a smooth periodic series
//! through the loop's knots (the ideal actuator: the set-point itself), through the LVDT's
//! calibration.
InputSignal DamperInput(bool ideal_actuator, const SineSetPoint& set_point, const LvdtInverse& model_input,
                        const StrokeTrajectory& trajectory, double t0, const std::string& label, int k) {
  if (ideal_actuator)
    return InputSignal([&set_point, &model_input, t0](double t) { return model_input(set_point.At(t0 + t)); });
  const double period = 1.0 / set_point.frequency;
  std::vector<double> knots(trajectory.knots() - 1);
  const double step = period / static_cast<double>(knots.size());
  for (std::size_t j = 0; j < knots.size(); ++j) knots[j] = trajectory.At(t0 + j * step).value;
  const InputSample first = trajectory.At(t0), last = trajectory.At(t0 + period);
  const InputSample mismatch{last.value - first.value, last.rate - first.rate, last.accel - first.accel};
  auto series = std::make_shared<FourierSignal>(
      FourierSignal::Fit(knots, period, 0.0, kStrokeHarmonicFloor, kMaxStrokeHarmonics, mismatch));
  spdlog::debug("experiment {} period {}: {} stroke harmonics", label, k, series->harmonics());
  return InputSignal([series, &model_input](double t) { return model_input(series->At(t)); });
}

//! The samples of one period without sensors (the one at t = period belongs to the next): rows
//! stroke, force, pressure, temperature when the model has it, set-point; one column a sample.
Eigen::MatrixXd CleanSamples(const TransientResult& result, const SineSetPoint& set_point, double t0,
                             const std::vector<double>& times, long n, long oversample, bool has_temperature) {
  const int rows = has_temperature ? 5 : 4;
  Eigen::MatrixXd clean(rows, n);
  const Eigen::VectorXd stroke_out = result.channel("stroke"), force_out = result.channel("force"),
                        pressure_out = result.channel("pressure");
  const Eigen::VectorXd temperature_out = has_temperature ? result.channel("temperature") : Eigen::VectorXd();
  for (long i = 0; i < n; ++i) {
    const long j = i * oversample;
    clean(0, i) = stroke_out[j];
    clean(1, i) = force_out[j];
    clean(2, i) = pressure_out[j];
    if (has_temperature) clean(3, i) = temperature_out[j];
    clean(rows - 1, i) = set_point.At(t0 + times[j]).value;
  }
  return clean;
}

//! How far a periodic run still is from its steady state, period after period.
class SettlingMeasure {
 public:
  //! The change of this period's force and pressure from the last period's, relative to their
  //! ranges (infinite for the first period), and what remains of it: the slowest mode decays
  //! geometrically, d_k = rho d_(k-1), so what remains after this period is d_k rho / (1 - rho),
  //! rho from the last few changes (as TransientSimulator::PeriodicSteadyState).
  void Update(const Eigen::VectorXd& force, const Eigen::VectorXd& pressure) {
    change_ = INFINITY;
    if (previous_force_.size() == force.size())
      change_ = std::max(RelativeChange(force, previous_force_), RelativeChange(pressure, previous_pressure_));
    previous_force_ = force;
    previous_pressure_ = pressure;
    remaining_ = INFINITY;
    if (!std::isfinite(change_)) return;
    changes_.push_back(change_);
    const int window = std::min<int>(3, static_cast<int>(changes_.size()) - 1);
    if (window > 0) {
      const double before = changes_[changes_.size() - 1 - window];
      const double rho = before > 0 ? std::pow(change_ / before, 1.0 / window) : 0.0;
      remaining_ = rho < 1.0 ? change_ * rho / (1.0 - rho) : change_;
    }
  }
  double change() const { return change_; }
  double remaining() const { return remaining_; }

 private:
  Eigen::VectorXd previous_force_, previous_pressure_;
  std::vector<double> changes_;
  double change_ = INFINITY, remaining_ = INFINITY;
};

//! The sample at which the controller's force-limit interlock stops the test: the first whose
//! damper output beyond `limit` falls in it; -1 when none does or there is no limit (0).
long ForceLimitTrip(const Eigen::VectorXd& force_out, double limit, long fine, long oversample) {
  if (!(limit > 0)) return -1;
  for (long j = 0; j <= fine; ++j)
    if (std::abs(force_out[j]) > limit) return j / oversample;
  return -1;
}

//! A period's readings before the sensors (stroke as an ideal LVDT reads it, force, absolute
//! pressure).
struct PeriodReadings {
  std::vector<double> stroke, force, pressure;
  bool tripped = false;  //!< cut at the force-limit interlock
};

//! The readings of `clean` up to where the controller's force-limit interlock stops the test:
//! the first sample beyond `limit` (0: none) ends them, and `report` says why.
PeriodReadings UpToForceLimit(const Eigen::MatrixXd& clean, const TransientResult& result, double limit, long fine,
                              long oversample, double t0, double sample_rate, PeriodicRunReport& report) {
  PeriodReadings r;
  r.stroke.assign(clean.row(0).begin(), clean.row(0).end());
  r.force.assign(clean.row(1).begin(), clean.row(1).end());
  r.pressure.assign(clean.row(2).begin(), clean.row(2).end());
  const long trip = ForceLimitTrip(result.channel("force"), limit, fine, oversample);
  if (trip < 0) return r;
  r.tripped = true;
  r.stroke.resize(trip + 1), r.force.resize(trip + 1), r.pressure.resize(trip + 1);
  report.interlock =
      fmt::format("force limit {:.1f} kN exceeded at t = {:.3f} s", limit * 1e-3, t0 + trip / sample_rate);
  return r;
}

//! What a periodic run acquired: the recorded periods, and every sample (an aborted test keeps
//! everything up to the trip).
struct PeriodicRecord {
  std::vector<std::vector<double>> stroke, force, pressure;
  std::vector<Eigen::MatrixXd> clean;
  std::vector<double> all_stroke, all_force, all_pressure;
  void KeepAcquired(const SampleBlock& block) {
    all_stroke.insert(all_stroke.end(), block.stroke.begin(), block.stroke.end());
    all_force.insert(all_force.end(), block.force.begin(), block.force.end());
    all_pressure.insert(all_pressure.end(), block.pressure.begin(), block.pressure.end());
  }
};

std::vector<double> Joined(const std::vector<std::vector<double>>& blocks, std::size_t reserve) {
  std::vector<double> all;
  all.reserve(reserve);
  for (const auto& b : blocks) all.insert(all.end(), b.begin(), b.end());
  return all;
}

//! The experiment of a periodic run: its channels (everything acquired when the interlock
//! stopped it), and the report's clean record and figures as attributes.
daq::Experiment PeriodicExperiment(const rig::MatrixEntry& entry, double sample_rate, long periods, long n,
                                   PeriodicRecord& record, const Acquisition& acquisition, bool gauge_pressure,
                                   bool has_temperature, const std::string& composition, PeriodicRunReport& report) {
  daq::Experiment e = rig::PeriodicExperimentOf(entry, periods, sample_rate);
  if (!report.interlock.empty()) {
    // Stopped by the interlock: no steady state; everything acquired up to the trip is kept.
    e.status = "aborted";
    e.periods = 0;
    record.stroke = {std::move(record.all_stroke)};
    record.force = {std::move(record.all_force)};
    record.pressure = {std::move(record.all_pressure)};
    record.clean.clear();
    e.extra_attributes["sim_interlock"] = report.interlock;
    spdlog::warn("experiment '{}' aborted: {}", entry.label, report.interlock);
  }
  const std::size_t reserve = static_cast<std::size_t>(n * periods);
  e.channels.push_back({"stroke", "m", "", Joined(record.stroke, reserve)});
  e.channels.push_back({"force", "N", "", Joined(record.force, reserve)});
  e.channels.push_back(acquisition.PressureChannel(Joined(record.pressure, reserve), gauge_pressure));
  const long count = static_cast<long>(e.channels.front().samples.size());
  e.time.resize(count);
  for (long i = 0; i < count; ++i) e.time[i] = static_cast<double>(i) / sample_rate;

  report.clean.resize(has_temperature ? 5 : 4, static_cast<Eigen::Index>(record.clean.size()) * n);
  for (std::size_t b = 0; b < record.clean.size(); ++b)
    report.clean.middleCols(static_cast<Eigen::Index>(b) * n, n) = record.clean[b];
  report.clean_rows = {"stroke", "force", "pressure"};
  if (has_temperature) report.clean_rows.push_back("temperature");
  report.clean_rows.push_back("set_point");
  report.simulated_seconds = report.periods_simulated * (1.0 / entry.frequency);

  e.extra_attributes["sim_model"] = composition;
  e.extra_attributes["sim_start_phase"] = Format(report.start_phase);
  e.extra_attributes["sim_settle_periods"] = std::to_string(report.settle_periods);
  e.extra_attributes["sim_settled"] = report.settled ? "true" : "false";
  e.extra_attributes["sim_settle_change"] = Format(report.settle_change);
  e.extra_attributes["sim_settle_remaining"] = Format(report.settle_remaining);
  e.extra_attributes["sim_record_change"] = Format(report.record_change);
  e.extra_attributes["sim_max_tracking_error"] = Format(report.actuator.max_tracking_error);
  e.extra_attributes["sim_max_valve_opening"] = Format(report.actuator.max_valve_opening);
  e.extra_attributes["sim_max_load_fraction"] = Format(report.actuator.max_load_fraction);
  if (report.actuator.max_load_fraction > 0.9)
    spdlog::warn("experiment '{}': the load reached {:.0f} % of the actuator's stall force (force limit)", entry.label,
                 100 * report.actuator.max_load_fraction);
  if (report.actuator.saturated_fraction > 0.0)
    spdlog::warn("experiment '{}': the servo valve saturated (flow limit) for {:.1f} % of a period", entry.label,
                 100 * report.actuator.saturated_fraction);
  return e;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// The rig

SimulatedRig::SimulatedRig(Truth truth) : truth_(std::move(truth)), model_(truth_.BuildModel(ident::Causality::kStrokeInput)) {
  truth_.Validate();
  theta_ = truth_.Parameters(model_).values();
}

daq::Session SimulatedRig::NewSession() const {
  daq::Session session;
  session.created_utc = daq::UtcNowIso8601();
  session.damper_serial = truth_.damper_serial;
  session.rig = fmt::format("{} [simulated: {}, truth {}]", truth_.rig, model_.composition(), truth_.source);
  RecordTruth(truth_, truth_.RecordedParameters(model_), model_.composition(), session);
  return session;
}

daq::Session SimulatedRig::RunMatrix(const rig::MatrixPlan& plan, const RigRunOptions& options,
                                     std::vector<PeriodicRunReport>* reports) const {
  const double rate = plan.sample_rate.value_or(truth_.acquisition.sample_rate);
  const long periods = plan.periods.value_or(truth_.acquisition.periods);
  // Check every experiment before simulating anything.
  for (const auto& e : plan.experiments) {
    if (!daq::WholeSamplesPerPeriod(rate, e.frequency, 16))
      throw TruthError(fmt::format("{}: experiment '{}': {} Hz sampled at {} Hz is not a whole number (>= 16) of "
                                   "samples per period",
                                   plan.source, e.label, e.frequency, rate));
  }
  daq::Session session = NewSession();
  std::mt19937_64 rng(options.seed);
  SimulationClock clock(options.clock);
  for (std::size_t index = 0; index < plan.experiments.size(); ++index) {
    const rig::MatrixEntry& e = plan.experiments[index];
    PeriodicRunReport report;
    clock.Start();
    try {
      session.experiments.push_back(RunPeriodic(e, rate, periods, rng, &report, &clock, options.sink, std::nullopt,
                                                daq::OrderSessionTime(index, plan.experiments.size())));
    } catch (const TransientError& error) {
      throw TransientError(fmt::format("experiment '{}': {}", e.label, error.what()), error.time, error.flag);
    }
    if (reports) reports->push_back(std::move(report));
  }
  return session;
}

daq::Experiment SimulatedRig::RunPeriodic(const rig::MatrixEntry& entry, double sample_rate, long periods,
                                          std::mt19937_64& rng, PeriodicRunReport* report_out, SimulationClock* clock,
                                          const SampleSink& sink, std::optional<double> start_phase,
                                          double session_time) const {
  const std::vector<double> theta = model_.AtExperiment(theta_, {session_time, entry.static_position});
  const auto wall_start = Clock::now();
  const AcquisitionOptions& acq = truth_.acquisition;
  const double f = entry.frequency, period = 1.0 / f;
  const std::optional<long> whole = daq::WholeSamplesPerPeriod(sample_rate, f, 16);
  if (!whole)
    throw TruthError(fmt::format("experiment '{}': {} Hz sampled at {} Hz is not a whole number (>= 16) of samples "
                                 "per period",
                                 entry.label, f, sample_rate));
  const long n = *whole;
  if (periods < 1) throw std::invalid_argument("periodic run: periods must be at least 1");
  const long oversample = std::max<long>(1, static_cast<long>(std::ceil(kLoadRate / sample_rate - 1e-9)));
  const long fine = n * oversample;  // damper outputs per period

  PeriodicRunReport report;
  report.label = entry.label;
  report.start_phase = start_phase ? *start_phase : std::uniform_real_distribution<double>(0.0, kTwoPi)(rng);
  const SineSetPoint set_point{f, entry.static_position, entry.amplitude, report.start_phase};

  // The LVDT's own calibration sits between the loop (which controls the reading y) and the
  // damper (whose measured stroke is q + theta12): u = (y - offset) / (1 + gain_error).
  const LvdtInverse model_input(truth_.sensors.stroke);

  const ServoActuator actuator(truth_.actuator);
  TransientOptions transient_options;
  transient_options.rtol = acq.rtol;
  const TransientSimulator simulator(model_, transient_options);
  ident::PeriodicSolverOptions solver_options;
  solver_options.scheme = ident::Scheme::kCentral4;
  solver_options.tolerance = 0.1;  // the damper's start: below what the settling then leaves
  ident::PeriodicSolver solver(model_, solver_options);
  PeriodicStart start =
      StartFromPeriodicSolutions(entry.label, set_point, model_input, actuator, solver, theta, report);

  // Period after period: actuator (against the load of the previous period), damper, sensors.
  std::vector<double> times(fine + 1);
  for (long i = 0; i <= fine; ++i) times[i] = static_cast<double>(i) * period / fine;
  const bool has_temperature = model_.has_term("heat-exchange");
  Acquisition acquisition(truth_, entry.label);
  PeriodicRecord record;
  SettlingMeasure settling;
  bool recording = false;
  int record_start = -1;
  double settle_change = INFINITY;
  std::optional<ident::PeriodicSolution> restart;
  for (int k = 0;; ++k) {
    const double t0 = k * period;
    if (k > 0) start.trajectory = actuator.Run(set_point, start.load, t0, period, start.actuator, &report.actuator);
    // While the loop still adapts to the damper's load (the first periods), the damper restarts
    // from the periodic solution for this period's stroke.
    if (k > 0 && k <= kRestartPeriods && !recording && start.at_set_point && !truth_.actuator.ideal)
      RestartFromPeriodicSolution(solver, theta, model_input, set_point, start.trajectory, t0, *start.at_set_point,
                                  restart, start.initial);
    const InputSignal signal =
        DamperInput(truth_.actuator.ideal, set_point, model_input, start.trajectory, t0, entry.label, k);
    const TransientResult result = simulator.Simulate(theta, signal, times, start.initial);
    report.ida_steps += result.steps;
    start.initial.unknowns.assign(result.unknowns.col(fine).data(),
                                  result.unknowns.col(fine).data() + result.unknowns.rows());
    // The load cell force of this period is the actuator's load in the next one.
    // (IDA's rate of the algebraic force is not reliable right after a restart: the load takes its
    // rate from differences of the samples.)
    {
      const Eigen::VectorXd force = result.unknowns.row(0).transpose();
      start.load = PeriodicLoad::FromGrid(std::span<const double>(force.data(), fine), period);
    }
    Eigen::MatrixXd clean = CleanSamples(result, set_point, t0, times, n, oversample, has_temperature);
    settling.Update(clean.row(1).transpose(), clean.row(2).transpose());
    const double change = settling.change(), remaining = settling.remaining();
    spdlog::debug("experiment {} period {}: change {:.3e}, {} IDA steps", entry.label, k, change, result.steps);
    const bool steady = change <= acq.settle_tolerance && remaining <= acq.settle_tolerance;
    if (recording) {
      report.record_change = std::max(report.record_change, change);
    } else if (steady || k + 1 >= acq.settle_periods_max) {
      report.settled = steady;
      settle_change = change;
      report.settle_remaining = remaining;
      if (!report.settled)
        spdlog::warn("experiment '{}': not settled after {} periods (last change {:.2e} of the range, {:.2e} "
                     "extrapolated, tolerance {:.1e}); recording anyway",
                     entry.label, k + 1, change, remaining, acq.settle_tolerance);
    }
    // Faults are timed from the first recorded sample; settling samples never see them.
    const double record_time = recording ? (k - record_start) * period : -INFINITY;
    const double limit = truth_.actuator.ideal ? 0.0 : truth_.actuator.force_limit;
    const PeriodReadings readings = UpToForceLimit(clean, result, limit, fine, oversample, t0, sample_rate, report);
    SampleBlock block = acquisition.Acquire(entry.label, readings.stroke, readings.force, readings.pressure,
                                            sample_rate, record_time, recording, rng);
    block.start_time = t0;
    Emit(sink, clock, block, t0);
    record.KeepAcquired(block);
    if (readings.tripped) {
      report.periods_simulated = k + 1;
      break;
    }
    if (recording) {
      record.stroke.push_back(std::move(block.stroke));
      record.force.push_back(std::move(block.force));
      record.pressure.push_back(std::move(block.pressure));
      record.clean.push_back(std::move(clean));
      if (static_cast<long>(record.stroke.size()) == periods) {
        report.periods_simulated = k + 1;
        break;
      }
    } else if (std::isfinite(settle_change)) {
      recording = true;
      record_start = k + 1;
      report.settle_periods = k + 1;
      report.settle_change = settle_change;
    }
  }

  daq::Experiment e = PeriodicExperiment(entry, sample_rate, periods, n, record, acquisition, acq.gauge_pressure,
                                         has_temperature, model_.composition(), report);
  report.wall_seconds = std::chrono::duration<double>(Clock::now() - wall_start).count();
  if (report_out) *report_out = std::move(report);
  return e;
}

// ---------------------------------------------------------------------------------------------
// Drop tests

daq::Session SimulatedRig::RunDropSession(const DropSpec& drop, const RigRunOptions& options,
                                          DropRunReport* report) const {
  daq::Session session = NewSession();
  std::mt19937_64 rng(options.seed);
  SimulationClock clock(options.clock);
  clock.Start();
  session.experiments.push_back(RunDrop(drop, rng, report, &clock, options.sink));
  return session;
}

daq::Experiment SimulatedRig::RunDrop(const DropSpec& drop, std::mt19937_64& rng, DropRunReport* report_out,
                                      SimulationClock* clock, const SampleSink& sink) const {
  const auto wall_start = Clock::now();
  if (!(drop.mass > 0) || !std::isfinite(drop.mass))
    throw std::invalid_argument(fmt::format("drop: the mass must be positive, got {} kg", drop.mass));
  if (!std::isfinite(drop.impact_velocity) || drop.impact_velocity < 0)
    throw std::invalid_argument(fmt::format("drop: the impact velocity must be >= 0, got {} m/s", drop.impact_velocity));
  if (!(drop.duration > 0) || !std::isfinite(drop.duration) || drop.duration > 3600)
    throw std::invalid_argument(fmt::format("drop: the duration must be 0..3600 s, got {} s", drop.duration));
  const double rate = truth_.acquisition.drop_sample_rate;
  const ident::Model force_model = truth_.BuildModel(ident::Causality::kForceInput);
  TransientOptions transient_options;
  transient_options.rtol = truth_.acquisition.rtol;
  const TransientSimulator simulator(force_model, transient_options);
  const int gravity = force_model.defaults().position_of_index(2);
  const DropLoad load{drop.mass, drop.impact_velocity, gravity >= 0 ? theta_[gravity] : 9.81};
  const std::vector<double> times = UniformTimes(drop.duration, rate);

  // A drop rig has no fixture between the force measurement and the damper: the moving mass is the
  // dropped mass alone (give it with the piston's share), so theta1 is zero here.
  std::vector<double> theta = theta_;
  if (const int mass = force_model.defaults().position_of_index(1); mass >= 0) theta[mass] = 0.0;
  DropRunReport report;
  report.result = simulator.Simulate(theta, load, times);
  const TransientResult& r = report.result;
  report.ida_steps = r.steps;
  const Eigen::VectorXd q = r.unknowns.row(0).transpose();
  report.peak_stroke = q.maxCoeff();
  report.final_stroke = q[q.size() - 1];
  report.peak_force = r.input.maxCoeff();
  if (force_model.has_term("heat-exchange")) {
    // Fit log(T - T_amb) over 20..80 % of the record, where the impact is long over.
    const ident::ParameterSet& d = force_model.defaults();
    const double ambient = -theta_[d.position_of_index(17)];
    const Eigen::VectorXd temperature = r.channel("temperature");
    double st = 0, sy = 0, stt = 0, sty = 0, sq = 0;
    int count = 0;
    for (std::size_t i = 0; i < times.size(); ++i) {
      if (times[i] < 0.2 * drop.duration || times[i] > 0.8 * drop.duration) continue;
      const double excess = temperature[i] - ambient;
      if (!(excess > 0)) continue;
      const double y = std::log(excess);
      st += times[i], sy += y, stt += times[i] * times[i], sty += times[i] * y, sq += q[i];
      ++count;
    }
    if (count > 10) {
      const double slope = (count * sty - st * sy) / (count * stt - st * st);
      report.thermal_time_constant_fit = slope < 0 ? -1.0 / slope : 0.0;
      const double mean_q = sq / count;
      report.thermal_time_constant_model =
          theta_[d.position_of_index(15)] / (theta_[d.position_of_index(16)] * (1.0 + theta_[d.position_of_index(6)] * mean_q));
    }
  }

  Acquisition acquisition(truth_, drop.label);
  const auto row = [](const Eigen::VectorXd& v) { return std::vector<double>(v.data(), v.data() + v.size()); };
  const Eigen::VectorXd lvdt = r.channel("stroke");
  std::vector<double> stroke_values = row(lvdt);
  SampleBlock block = acquisition.Acquire(drop.label, stroke_values, row(r.input), row(r.channel("pressure")), rate,
                                          0.0, true, rng);
  Emit(sink, clock, block, 0.0);

  daq::Experiment e;
  e.label = drop.label;
  e.kind = daq::ExperimentKind::kDrop;
  e.sample_rate = rate;
  e.drop_mass = drop.mass;
  e.impact_velocity = drop.impact_velocity;
  e.time = times;
  e.channels.push_back({"stroke", "m", "", std::move(block.stroke)});
  e.channels.push_back({"force", "N", "", std::move(block.force)});
  e.channels.push_back(acquisition.PressureChannel(std::move(block.pressure), truth_.acquisition.gauge_pressure));
  e.extra_attributes["sim_model"] = force_model.composition();
  report.wall_seconds = std::chrono::duration<double>(Clock::now() - wall_start).count();
  if (report_out) *report_out = std::move(report);
  return e;
}

}  // namespace strut::sim
