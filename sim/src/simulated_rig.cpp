#include "strut/sim/simulated_rig.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fmt/format.h>
#include <numbers>

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
  ident::ParameterSet parameters = model_.defaults();
  parameters.values() = theta_;
  RecordTruth(truth_, parameters, model_.composition(), session);
  return session;
}

daq::Session SimulatedRig::RunMatrix(const rig::MatrixPlan& plan, const RigRunOptions& options,
                                     std::vector<PeriodicRunReport>* reports) const {
  const double rate = plan.sample_rate.value_or(truth_.acquisition.sample_rate);
  const long periods = plan.periods.value_or(truth_.acquisition.periods);
  // Check every experiment before simulating anything.
  for (const auto& e : plan.experiments) {
    const double per_period = rate / e.frequency;
    if (std::abs(per_period - std::round(per_period)) > 1e-9 * per_period || per_period < 16)
      throw TruthError(fmt::format("{}: experiment '{}': {} Hz sampled at {} Hz is not a whole number (>= 16) of "
                                   "samples per period",
                                   plan.source, e.label, e.frequency, rate));
  }
  daq::Session session = NewSession();
  std::mt19937_64 rng(options.seed);
  SimulationClock clock(options.clock);
  for (const auto& e : plan.experiments) {
    PeriodicRunReport report;
    clock.Start();
    try {
      session.experiments.push_back(RunPeriodic(e, rate, periods, rng, &report, &clock, options.sink));
    } catch (const TransientError& error) {
      throw TransientError(fmt::format("experiment '{}': {}", e.label, error.what()), error.time, error.flag);
    }
    if (reports) reports->push_back(std::move(report));
  }
  return session;
}

daq::Experiment SimulatedRig::RunPeriodic(const rig::MatrixEntry& entry, double sample_rate, long periods,
                                          std::mt19937_64& rng, PeriodicRunReport* report_out, SimulationClock* clock,
                                          const SampleSink& sink, std::optional<double> start_phase) const {
  const auto wall_start = Clock::now();
  const AcquisitionOptions& acq = truth_.acquisition;
  const double f = entry.frequency, period = 1.0 / f;
  const long n = std::lround(sample_rate / f);
  if (std::abs(sample_rate / f - n) > 1e-9 * n || n < 16)
    throw TruthError(fmt::format("experiment '{}': {} Hz sampled at {} Hz is not a whole number (>= 16) of samples "
                                 "per period",
                                 entry.label, f, sample_rate));
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

  // 1. The periodic steady state at the set-point gives the load for settling the actuator; 2. the
  // periodic steady state for the actual stroke of the settled actuator is the damper's start.
  // Both are shortcuts: a real rig would run the sine for minutes until the gas temperature settles.
  const auto grid_input = [&](const std::function<InputSample(double)>& stroke) {
    ident::PeriodicInput in{f, std::vector<double>(kStartGrid)};
    for (int mu = 0; mu < kStartGrid; ++mu) in.values[mu] = model_input(stroke(mu * period / kStartGrid)).value;
    return in;
  };
  PeriodicLoad load = PeriodicLoad::Constant(0.0);
  std::optional<ident::PeriodicSolution> start;
  try {
    start = solver.Solve(grid_input([&](double t) { return set_point.At(t); }), theta_);
    const Eigen::VectorXd force = start->channel("force");
    load = PeriodicLoad::FromGrid(std::span<const double>(force.data(), force.size()), period);
  } catch (const ident::PeriodicSolverError& e) {
    spdlog::warn("experiment '{}': no periodic solution at the set-point ({}); settling from the static state",
                 entry.label, e.what());
  }
  ServoActuator::State state = actuator.SettledState(set_point, load, 0.0, std::max(period, 0.5));
  StrokeTrajectory trajectory = actuator.Run(set_point, load, 0.0, period, state, &report.actuator);
  InitialState initial;
  if (start) {
    try {
      const ident::PeriodicSolution actual =
          solver.Solve(grid_input([&](double t) { return trajectory.At(t); }), theta_, &*start);
      initial.unknowns.assign(actual.unknowns.col(0).data(), actual.unknowns.col(0).data() + actual.unknowns.rows());
      report.started_from_periodic_solution = true;
    } catch (const ident::PeriodicSolverError& e) {
      spdlog::warn("experiment '{}': no periodic solution for the actual stroke ({}); settling from the static state",
                   entry.label, e.what());
    }
  }

  // 3. Period after period: actuator (against the load of the previous period), damper, sensors.
  std::vector<double> times(fine + 1);
  for (long i = 0; i <= fine; ++i) times[i] = static_cast<double>(i) * period / fine;
  const bool has_temperature = model_.has_term("heat-exchange");
  Acquisition acquisition(truth_, entry.label);
  std::vector<std::vector<double>> record_stroke, record_force, record_pressure;
  std::vector<Eigen::MatrixXd> record_clean;
  Eigen::VectorXd previous_force, previous_pressure;
  bool recording = false;
  int record_start = -1;
  double settle_change = INFINITY;
  std::vector<double> changes;
  std::vector<double> all_stroke, all_force, all_pressure;  // every acquired sample, for an aborted test
  std::optional<ident::PeriodicSolution> restart;
  for (int k = 0;; ++k) {
    const double t0 = k * period;
    if (k > 0) trajectory = actuator.Run(set_point, load, t0, period, state, &report.actuator);
    // While the loop still adapts to the damper's load (the first periods), the damper restarts
    // from the periodic solution for this period's stroke: its slow thermal mode (a minute deep in
    // the stroke) then starts settled instead of decaying from the first guess.
    if (k > 0 && k <= kRestartPeriods && !recording && start && !truth_.actuator.ideal) {
      try {
        restart = solver.Solve(grid_input([&](double t) { return trajectory.At(t0 + t); }), theta_,
                               restart ? &*restart : &*start);
        initial.unknowns.assign(restart->unknowns.col(0).data(),
                                restart->unknowns.col(0).data() + restart->unknowns.rows());
      } catch (const ident::PeriodicSolverError&) {
        // keep integrating from where the last period ended
      }
    }
    // The damper sees the actual stroke as a smooth periodic series through the loop's knots (the
    // ideal actuator: the set-point itself).
    InputSignal signal;
    if (truth_.actuator.ideal) {
      signal = InputSignal([&set_point, &model_input, t0](double t) { return model_input(set_point.At(t0 + t)); });
    } else {
      std::vector<double> knots(trajectory.knots() - 1);
      const double step = period / static_cast<double>(knots.size());
      for (std::size_t j = 0; j < knots.size(); ++j) knots[j] = trajectory.At(t0 + j * step).value;
      const InputSample first = trajectory.At(t0), last = trajectory.At(t0 + period);
      const InputSample mismatch{last.value - first.value, last.rate - first.rate, last.accel - first.accel};
      auto series = std::make_shared<FourierSignal>(
          FourierSignal::Fit(knots, period, 0.0, kStrokeHarmonicFloor, kMaxStrokeHarmonics, mismatch));
      spdlog::debug("experiment {} period {}: {} stroke harmonics", entry.label, k, series->harmonics());
      signal = InputSignal([series, &model_input](double t) { return model_input(series->At(t)); });
    }
    const TransientResult result = simulator.Simulate(theta_, signal, times, initial);
    report.ida_steps += result.steps;
    initial.unknowns.assign(result.unknowns.col(fine).data(), result.unknowns.col(fine).data() + result.unknowns.rows());
    // The load cell force of this period is the actuator's load in the next one.
    // (IDA's rate of the algebraic force is not reliable right after a restart: the load takes its
    // rate from differences of the samples.)
    {
      const Eigen::VectorXd force = result.unknowns.row(0).transpose();
      load = PeriodicLoad::FromGrid(std::span<const double>(force.data(), fine), period);
    }
    // The samples of this period (the one at t = period belongs to the next).
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
    const Eigen::VectorXd force_now = clean.row(1).transpose(), pressure_now = clean.row(2).transpose();
    double change = INFINITY;
    if (previous_force.size() == n)
      change = std::max(RelativeChange(force_now, previous_force), RelativeChange(pressure_now, previous_pressure));
    previous_force = force_now;
    previous_pressure = pressure_now;
    spdlog::debug("experiment {} period {}: change {:.3e}, {} IDA steps", entry.label, k, change, result.steps);

    // The slowest mode decays geometrically, d_k = rho d_(k-1), so what remains after this period is
    // d_k rho / (1 - rho), rho from the last few changes (as TransientSimulator::PeriodicSteadyState).
    double remaining = INFINITY;
    if (std::isfinite(change)) {
      changes.push_back(change);
      const int window = std::min<int>(3, static_cast<int>(changes.size()) - 1);
      if (window > 0) {
        const double before = changes[changes.size() - 1 - window];
        const double rho = before > 0 ? std::pow(change / before, 1.0 / window) : 0.0;
        remaining = rho < 1.0 ? change * rho / (1.0 - rho) : change;
      }
    }
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
    std::vector<double> stroke_values(n), force_values(n), pressure_values(n);
    for (long i = 0; i < n; ++i) {
      stroke_values[i] = clean(0, i);
      force_values[i] = clean(1, i);
      pressure_values[i] = clean(2, i);
    }
    // Force-limit interlock: the controller stops the test at the first sample beyond the limit.
    const double limit = truth_.actuator.ideal ? 0.0 : truth_.actuator.force_limit;
    long trip = -1;
    if (limit > 0)
      for (long j = 0; j <= fine && trip < 0; ++j)
        if (std::abs(force_out[j]) > limit) trip = j / oversample;
    if (trip >= 0) {
      stroke_values.resize(trip + 1), force_values.resize(trip + 1), pressure_values.resize(trip + 1);
      report.interlock = fmt::format("force limit {:.1f} kN exceeded at t = {:.3f} s", limit * 1e-3,
                                     t0 + trip / sample_rate);
    }
    SampleBlock block = acquisition.Acquire(entry.label, stroke_values, force_values, pressure_values, sample_rate,
                                            record_time, recording, rng);
    block.start_time = t0;
    Emit(sink, clock, block, t0);
    all_stroke.insert(all_stroke.end(), block.stroke.begin(), block.stroke.end());
    all_force.insert(all_force.end(), block.force.begin(), block.force.end());
    all_pressure.insert(all_pressure.end(), block.pressure.begin(), block.pressure.end());
    if (trip >= 0) {
      report.periods_simulated = k + 1;
      break;
    }
    if (recording) {
      record_stroke.push_back(std::move(block.stroke));
      record_force.push_back(std::move(block.force));
      record_pressure.push_back(std::move(block.pressure));
      record_clean.push_back(std::move(clean));
      if (static_cast<long>(record_stroke.size()) == periods) {
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

  daq::Experiment e;
  e.label = entry.label;
  e.kind = daq::ExperimentKind::kPeriodic;
  e.sample_rate = sample_rate;
  e.frequency = f;
  e.amplitude = entry.amplitude;
  e.static_position = entry.static_position;
  e.periods = periods;
  e.group = entry.group;
  const auto join = [&](const std::vector<std::vector<double>>& blocks) {
    std::vector<double> all;
    all.reserve(n * periods);
    for (const auto& b : blocks) all.insert(all.end(), b.begin(), b.end());
    return all;
  };
  if (!report.interlock.empty()) {
    // Stopped by the interlock: no steady state; everything acquired up to the trip is kept.
    e.status = "aborted";
    e.periods = 0;
    record_stroke = {std::move(all_stroke)};
    record_force = {std::move(all_force)};
    record_pressure = {std::move(all_pressure)};
    record_clean.clear();
    e.extra_attributes["sim_interlock"] = report.interlock;
    spdlog::warn("experiment '{}' aborted: {}", entry.label, report.interlock);
  }
  e.channels.push_back({"stroke", "m", "", join(record_stroke)});
  e.channels.push_back({"force", "N", "", join(record_force)});
  e.channels.push_back(acquisition.PressureChannel(join(record_pressure), acq.gauge_pressure));
  const long count = static_cast<long>(e.channels.front().samples.size());
  e.time.resize(count);
  for (long i = 0; i < count; ++i) e.time[i] = static_cast<double>(i) / sample_rate;

  report.clean.resize(has_temperature ? 5 : 4, static_cast<Eigen::Index>(record_clean.size()) * n);
  for (std::size_t b = 0; b < record_clean.size(); ++b)
    report.clean.middleCols(static_cast<Eigen::Index>(b) * n, n) = record_clean[b];
  report.clean_rows = {"stroke", "force", "pressure"};
  if (has_temperature) report.clean_rows.push_back("temperature");
  report.clean_rows.push_back("set_point");
  report.simulated_seconds = report.periods_simulated * period;
  report.wall_seconds = std::chrono::duration<double>(Clock::now() - wall_start).count();

  e.extra_attributes["sim_model"] = model_.composition();
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
