// The simulated servo controller with its plant (simulated_controller.h).
#include "strut/sim/simulated_controller.h"

#include <spdlog/spdlog.h>
#include <time.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <fmt/format.h>
#include <numbers>
#include <stdexcept>

#include "rig_acquisition.h"
#include "strut/sim/actuator.h"
#include "strut/sim/transient.h"

namespace strut::sim {

using daq::ControllerCommand;
using daq::ControllerState;
namespace status_bits = daq::status_bits;
namespace fault_bits = daq::fault_bits;

namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;
// The damper's force is kept at least this often, for the load the actuator feels, Hz.
constexpr double kLoadRate = 1000.0;
// Longest sine period whose force history is kept for the periodic load prediction, s.
constexpr double kMaxHistorySeconds = 600.0;
// A polynomial stands for the actual stroke of a chunk when it is this close to the loop's knots:
// m (value) and m/s^2 (acceleration: 1e-3 m/s^2 is 0.04 N of the 40 kg fixture's inertia).
constexpr double kSmoothStrokeError = 1e-9;
constexpr double kSmoothAccelError = 0.1;

double ThreadCpuSeconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

std::string Mm(double metres) { return fmt::format("{:.2f} mm", metres * 1e3); }

}  // namespace

// ---------------------------------------------------------------------------------------------
// CommandProgram

CommandProgram CommandProgram::Locked(double start) { return {.kind = Kind::kLocked, .start = start}; }

CommandProgram CommandProgram::Move(double start, double from, double to, double rate) {
  return {.kind = Kind::kMove, .start = start, .from = from, .to = to, .rate = rate};
}

CommandProgram CommandProgram::Sine(double start, double mean, double amplitude, double frequency, int ramp_cycles) {
  return {.kind = Kind::kSine,
          .start = start,
          .from = mean,
          .to = mean,
          .mean = mean,
          .amplitude = amplitude,
          .frequency = frequency,
          .ramp_cycles = ramp_cycles};
}

double CommandProgram::Envelope(double t) const {
  if (kind != Kind::kSine || t <= start) return 0.0;
  if (frequency <= 0) return t < stop_at ? 1.0 : 0.0;  // a sine of frequency 0 holds the mean
  const auto ramp_in = [&](double x) {
    return ramp_cycles == 0 ? 1.0 : std::min(1.0, (x - start) * frequency / ramp_cycles);
  };
  if (t < stop_at) return ramp_in(t);
  const double at_stop = ramp_in(stop_at);
  if (ramp_cycles == 0) return 0.0;
  return at_stop * std::max(0.0, 1.0 - (t - stop_at) * frequency / ramp_cycles);
}

InputSample CommandProgram::At(double t) const {
  switch (kind) {
    case Kind::kLocked:
      return {};
    case Kind::kMove: {
      const double distance = to - from, duration = std::abs(distance) / rate;
      const double s = std::max(0.0, t - start);
      if (s >= duration) return {to, 0.0, 0.0};
      return {from + std::copysign(rate * s, distance), std::copysign(rate, distance), 0.0};
    }
    case Kind::kSine: {
      if (t <= start || frequency <= 0) return {mean, 0.0, 0.0};
      // The envelope is piecewise linear in time; its slope on the piece that holds t.
      const double e = Envelope(t);
      double slope = 0.0;
      if (ramp_cycles > 0) {
        const double ramp_in_end = start + ramp_cycles / frequency;
        if (t < stop_at && t < ramp_in_end) slope = frequency / ramp_cycles;
        if (t >= stop_at && e > 0) slope = -Envelope(stop_at) * frequency / ramp_cycles;
      }
      const double w = kTwoPi * frequency, phase = w * (t - start);
      const double s = std::sin(phase), c = std::cos(phase);
      const double a = amplitude;
      return {mean + a * e * s, a * (slope * s + e * w * c), a * (2 * slope * w * c - e * w * w * s)};
    }
  }
  return {};
}

double CommandProgram::End() const {
  switch (kind) {
    case Kind::kLocked:
      return start;
    case Kind::kMove:
      return start + std::abs(to - from) / rate;
    case Kind::kSine:
      if (!std::isfinite(stop_at)) return INFINITY;
      return stop_at + (ramp_cycles == 0 || frequency <= 0 ? 0.0 : ramp_cycles / frequency);
  }
  return start;
}

double CommandProgram::NextCycleBoundary(double t) const {
  if (kind != Kind::kSine || frequency <= 0 || t <= start) return std::max(t, start);
  // Guard against a boundary that t sits on up to rounding: it counts as reached.
  const double cycles = std::ceil((t - start) * frequency - 1e-9);
  return start + cycles / frequency;
}

std::uint32_t CommandProgram::Cycles(double t) const {
  if (kind != Kind::kSine || frequency <= 0 || t <= start) return 0;
  const double until = std::min(t, End());
  return static_cast<std::uint32_t>(std::floor((until - start) * frequency + 1e-9));
}

// ---------------------------------------------------------------------------------------------
// Options

bool SimulatedControllerOptions::IsValid(std::string* error) const {
  const auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (initial_stroke && (!std::isfinite(*initial_stroke) || std::abs(*initial_stroke) > daq::SetPoint::kMaxAbsStroke))
    return fail(fmt::format("initial_stroke must be finite and within +-{} m, got {}", daq::SetPoint::kMaxAbsStroke,
                            *initial_stroke));
  if (!std::isfinite(following_error_limit) || following_error_limit < 0)
    return fail(fmt::format("following_error_limit must be 0 (off) or positive, got {} m", following_error_limit));
  if (!std::isfinite(chunk_seconds) || chunk_seconds <= 0 || chunk_seconds > 1.0)
    return fail(fmt::format("chunk_seconds must be in (0, 1] s, got {}", chunk_seconds));
  return true;
}

// ---------------------------------------------------------------------------------------------
// The plant

//! The damper's force on a fine grid (kLoadRate or finer), oldest first: what the load predictor
//! extrapolates from.
struct ForceHistory {
  double step = 0.0;        //!< s between values
  double first_time = 0.0;  //!< time of values.front()
  std::deque<double> values;

  double last_time() const { return first_time + step * static_cast<double>(values.size() - 1); }
  bool Covers(double t) const {
    return values.size() >= 4 && t >= first_time + step - 1e-12 && t <= last_time() - step + 1e-12;
  }
  //! Cubic Hermite through the values with central-difference slopes. @pre Covers(t).
  InputSample At(double t) const {
    const double x = (t - first_time) / step;
    const std::size_t n = values.size();
    const std::size_t k = std::clamp<std::size_t>(static_cast<std::size_t>(std::max(0.0, std::floor(x))), 1, n - 3);
    const double s = x - static_cast<double>(k);
    const double p0 = values[k], p1 = values[k + 1];
    const double m0 = 0.5 * (values[k + 1] - values[k - 1]), m1 = 0.5 * (values[k + 2] - values[k]);
    const double s2 = s * s, s3 = s2 * s;
    const double value = (2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * m0 + (-2 * s3 + 3 * s2) * p1 + (s3 - s2) * m1;
    const double ds = (6 * s2 - 6 * s) * p0 + (3 * s2 - 4 * s + 1) * m0 + (-6 * s2 + 6 * s) * p1 + (3 * s2 - 2 * s) * m1;
    return {value, ds / step, 0.0};
  }
  void Push(double value, std::size_t keep) {
    values.push_back(value);
    while (values.size() > keep) {
      values.pop_front();
      first_time += step;
    }
  }
};

//! What changes as the plant runs: copyable, so a chunk can be computed again from its start.
struct PlantState {
  long index = 0;  //!< sample index of the plant's time (t = index / rate)
  ServoActuator::State servo;
  InitialState damper;  //!< the damper's unknowns at t (empty: static equilibrium at the input)
  Acquisition acquisition;
  std::mt19937_64 rng;
  ForceHistory force;
  ActuatorStats actuator_stats;
};

struct SimulatedController::Plant {
  Plant(const Truth& truth, const ident::Model& m, std::vector<double> th, unsigned long seed, double start_stroke,
        double rate, long oversample)
      : model(m),
        theta(std::move(th)),
        actuator(truth.actuator),
        simulator(model, [&] {
          TransientOptions o;
          o.rtol = truth.acquisition.rtol;
          return o;
        }()),
        lvdt(truth.sensors.stroke),
        top_out(truth.top_out),
        stroke_offset([&] {
          const int k = model.defaults().position_of_index(12);
          return k >= 0 ? theta[k] : 0.0;
        }()),
        state{0, {start_stroke, 0.0}, {}, Acquisition(truth, "stream"), std::mt19937_64(seed), {}, {}} {
    state.force.step = 1.0 / (rate * static_cast<double>(oversample));
    if (truth.has_effect("charge-loss"))
      spdlog::warn("{}: the served rig holds the charge of the session's start: charge-loss leaks only in `strut sim "
                   "matrix` runs, where each experiment has its place in the session",
                   truth.source);
  }
  ident::Model model;
  std::vector<double> theta;
  ServoActuator actuator;
  TransientSimulator simulator;
  LvdtInverse lvdt;
  TopOutContact top_out;
  double stroke_offset;  //!< theta12: the model's measured stroke less the true stroke
  PlantState state;
};

struct SimulatedController::DamperChannels {
  Eigen::VectorXd stroke, force, pressure;
};

//! One chunk's results.
struct SimulatedController::Chunk {
  SampleBlock readings;  //!< the chunk's samples as the sensors read them
  std::vector<double> stroke, command, force, pressure;  //!< noise-free, per sample (command: NaN when off)
  PlantSnapshot end;     //!< the plant at the chunk's end
  long ida_steps = 0;
  double fit_value_error = 0.0, fit_accel_error = 0.0;  //!< the worst of the pieces' polynomials
  bool smooth = false;  //!< the damper saw polynomials over the whole chunk (else the knots somewhere)
};

SimulatedController::SimulatedController(Truth truth, SimulatedControllerOptions options)
    : truth_(std::move(truth)), options_(options) {
  truth_.Validate();
  std::string error;
  if (!options_.IsValid(&error)) throw std::invalid_argument("simulated controller: " + error);
  rate_ = truth_.acquisition.sample_rate;
  chunk_samples_ = std::max<long>(1, std::lround(options_.chunk_seconds * rate_));
  chunk_ = static_cast<double>(chunk_samples_) / rate_;
  const long oversample = std::max<long>(1, static_cast<long>(std::ceil(kLoadRate / rate_ - 1e-9)));
  const ident::Model model = truth_.BuildModel(ident::Causality::kStrokeInput);
  // The piston rests on its top-out stop unless told otherwise, and never pressed into it. The
  // reading grows with the true stroke (the LVDT's gain is positive), so "beyond" is "below".
  const double top_out = truth_.TopOutReading();
  double rest = options_.initial_stroke.value_or(top_out);
  if (truth_.top_out.stiffness > 0 && rest < top_out) {
    spdlog::warn("{}: the piston cannot rest at {:.4f} m, beyond its top-out stop at {:.4f} m: it rests on the stop",
                 truth_.source, rest, top_out);
    rest = top_out;
  }
  plant_ = std::make_unique<Plant>(truth_, model, truth_.Parameters(model).values(), options_.seed, rest, rate_,
                                   oversample);
  // The piston rests locked at the initial stroke; the first chunk starts the damper there.
  program_ = CommandProgram::Locked(0.0);
  snapshot_.stroke = rest;
  snapshot_.command = rest;
  stroke_reading_ = rest;
}

SimulatedController::~SimulatedController() = default;

namespace {

// The worst misfit of a polynomial to the loop's knots within [from, to].
std::pair<double, double> KnotMisfit(const ChebyshevSignal& fit, const StrokeTrajectory& stroke, double t0, double t1,
                                     double from, double to) {
  double worst_value = 0.0, worst_accel = 0.0;
  for (std::size_t k = 0; k < stroke.knots(); ++k) {
    const double t = t0 + (t1 - t0) * static_cast<double>(k) / static_cast<double>(stroke.knots() - 1);
    if (t < from - 1e-12 || t > to + 1e-12) continue;
    const InputSample a = fit.At(t), b = stroke.At(t);
    worst_value = std::max(worst_value, std::abs(a.value - b.value));
    worst_accel = std::max(worst_accel, std::abs(a.accel - b.accel));
  }
  return {worst_value, worst_accel};
}

}  // namespace

std::vector<SimulatedController::StrokePiece> SimulatedController::SmoothPieces(const StrokeTrajectory& stroke,
                                                                                  double t0, double fine,
                                                                                  long fine_count, Chunk& out) {
  // Halving stops at a quarter of the chunk (12.5 ms): below that the knots cost little more than
  // IDA's restarts at the pieces' ends.
  constexpr int kMaxHalvings = 2;
  const double t1 = t0 + static_cast<double>(fine_count) * fine;
  std::vector<StrokePiece> pieces;
  out.smooth = true;
  out.fit_value_error = out.fit_accel_error = 0.0;
  const std::function<void(long, long, int)> cover = [&](long from, long to, int halvings) {
    const double a = t0 + static_cast<double>(from) * fine, b = t0 + static_cast<double>(to) * fine;
    double value = 0.0, accel = 0.0;
    for (int degree : {16, 32}) {
      ChebyshevSignal fit = ChebyshevSignal::Fit([&stroke](double t) { return stroke.At(t).value; }, a, b, degree);
      std::tie(value, accel) = KnotMisfit(fit, stroke, t0, t1, a, b);
      if (value <= kSmoothStrokeError && accel <= kSmoothAccelError) {
        out.fit_value_error = std::max(out.fit_value_error, value);
        out.fit_accel_error = std::max(out.fit_accel_error, accel);
        pieces.push_back({from, to, std::move(fit)});
        return;
      }
    }
    if (halvings == kMaxHalvings || to - from < 2) {
      out.smooth = false;
      out.fit_value_error = std::max(out.fit_value_error, value);
      out.fit_accel_error = std::max(out.fit_accel_error, accel);
      pieces.push_back({from, to, std::nullopt});
      return;
    }
    const long middle = (from + to) / 2;
    cover(from, middle, halvings + 1);
    cover(middle, to, halvings + 1);
  };
  cover(0, fine_count, 0);
  return pieces;
}

SimulatedController::DamperChannels SimulatedController::IntegrateDamper(Plant& plant, const StrokeTrajectory& stroke,
                                                                         double t0, long fine_count, Chunk& out) {
  PlantState& s = plant.state;
  const double fine = s.force.step;
  const LvdtInverse& lvdt = plant.lvdt;
  DamperChannels d{Eigen::VectorXd(fine_count + 1), Eigen::VectorXd(fine_count + 1), Eigen::VectorXd(fine_count + 1)};
  out.ida_steps = 0;
  // One IDA run per piece, each from where the last ended: the pieces meet within 1e-9 m, which an
  // integration across the join would take for a discontinuity of the input.
  for (const StrokePiece& p : SmoothPieces(stroke, t0, fine, fine_count, out)) {
    const long count = p.to - p.from;
    std::vector<double> times(static_cast<std::size_t>(count) + 1);
    for (long j = 0; j <= count; ++j) times[j] = static_cast<double>(j) * fine;
    const double start = t0 + static_cast<double>(p.from) * fine;
    const InputSignal input([&p, &stroke, &lvdt, start](double t) {
      return lvdt(p.fit ? p.fit->At(start + t) : stroke.At(start + t));
    });
    const TransientResult r = plant.simulator.Simulate(plant.theta, input, times, s.damper);
    out.ida_steps += r.steps;
    s.damper.unknowns.assign(r.unknowns.col(count).data(), r.unknowns.col(count).data() + r.unknowns.rows());
    d.stroke.segment(p.from, count + 1) = r.channel("stroke");
    d.force.segment(p.from, count + 1) = r.channel("force");
    d.pressure.segment(p.from, count + 1) = r.channel("pressure");
    // The top-out stop beside the damper's own force (it acts on the axle, not on the gas):
    // k d (1 - alpha q') toward compression for the penetration d = -q > 0, never pulling.
    if (plant.top_out.stiffness > 0) {
      for (long j = 0; j <= count; ++j) {
        const InputSample u = input(times[j]);
        const double penetration = plant.stroke_offset - u.value;
        if (penetration <= 0) continue;
        const double factor = std::max(0.0, 1.0 - plant.top_out.dissipation * u.rate);
        d.force[p.from + j] -= plant.top_out.stiffness * penetration * factor;
      }
    }
  }
  return d;
}

void SimulatedController::Integrate(Plant& plant, const CommandProgram& program, double closed_from,
                                    Chunk& out) const {
  PlantState& s = plant.state;
  const long n = chunk_samples_;
  const double h = 1.0 / rate_;
  const double t0 = static_cast<double>(s.index) * h, t1 = static_cast<double>(s.index + n) * h;
  const double fine = s.force.step;
  const long per_sample = std::lround(h / fine);
  const long fine_count = n * per_sample;
  const double closed = program.kind == CommandProgram::Kind::kLocked ? -INFINITY : closed_from;

  // The load the actuator feels over the chunk, predicted (the damper's force comes after):
  // a steady sine repeats the previous period's force (exact once the response is periodic);
  // otherwise the force is extrapolated by the parabola through the last chunk's start, middle
  // and end (a slope from the last samples alone would follow friction's sharp reversals).
  ServoActuator::Signal load;
  const ForceHistory& history = s.force;
  const double f_now = history.values.empty() ? 0.0 : history.values.back();
  const double period = program.kind == CommandProgram::Kind::kSine && program.frequency > 0 ? 1.0 / program.frequency
                                                                                               : INFINITY;
  const double full_from = program.kind == CommandProgram::Kind::kSine
                               ? program.start + (program.ramp_cycles == 0 ? 0.0 : program.ramp_cycles * period)
                               : INFINITY;
  if (std::isfinite(period) && t0 - period >= full_from && t0 <= program.stop_at && history.Covers(t0 - period) &&
      history.Covers(t1 - period)) {
    const double offset = f_now - history.At(t0 - period).value;
    load = [&history, period, offset](double t) {
      InputSample f = history.At(t - period);
      f.value += offset;
      return f;
    };
  } else if (history.values.size() > static_cast<std::size_t>(fine_count)) {
    const std::size_t last = history.values.size() - 1, m = static_cast<std::size_t>(std::max<long>(1, fine_count / 2));
    const double p0 = history.values[last], p1 = history.values[last - m], p2 = history.values[last - 2 * m];
    const double span = static_cast<double>(m) * fine;
    const double d1 = 0.5 * (3 * p0 - 4 * p1 + p2), d2 = p0 - 2 * p1 + p2;
    load = [=](double t) {
      const double x = (t - t0) / span;
      return InputSample{p0 + x * d1 + 0.5 * x * x * d2, (d1 + x * d2) / span, 0.0};
    };
  } else {
    load = [f_now](double) { return InputSample{f_now, 0.0, 0.0}; };
  }

  const ServoActuator::Signal command = [&program](double t) { return program.At(t); };
  const StrokeTrajectory stroke = plant.actuator.Run(command, load, t0, t1 - t0, s.servo, &s.actuator_stats, closed);

  // The damper over the chunk, from where the last one ended; the force on the fine grid.
  const DamperChannels d = IntegrateDamper(plant, stroke, t0, fine_count, out);
  const Eigen::VectorXd &stroke_out = d.stroke, &force_out = d.force, &pressure_out = d.pressure;
  const std::size_t keep = static_cast<std::size_t>(
      std::ceil(std::min(std::isfinite(period) ? period : 0.0, kMaxHistorySeconds) / fine) + 2 * fine_count + 8);
  if (s.force.values.empty()) {
    s.force.first_time = t0;
    s.force.Push(force_out[0], keep);
  }
  for (long j = 1; j <= fine_count; ++j) s.force.Push(force_out[j], keep);

  // The samples of [t0, t1) through the sensors (the one at t1 opens the next chunk).
  out.stroke.resize(n), out.command.resize(n), out.force.resize(n), out.pressure.resize(n);
  std::vector<double> lvdt_values(n);
  for (long i = 0; i < n; ++i) {
    const long j = i * per_sample;
    const double t = t0 + static_cast<double>(i) * h;
    lvdt_values[i] = stroke_out[j];
    out.stroke[i] = stroke.At(t).value;
    out.command[i] = t >= closed ? NAN : program.At(t).value;
    out.force[i] = force_out[j];
    out.pressure[i] = pressure_out[j];
  }
  out.readings = s.acquisition.Acquire("stream", lvdt_values, out.force, out.pressure, rate_, t0, false, s.rng);
  s.index += n;

  out.end.time = t1;
  out.end.stroke = stroke.At(t1).value;
  out.end.force = force_out[fine_count];
  out.end.pressure = pressure_out[fine_count];
  out.end.hydraulics = t1 < closed;
  out.end.command = out.end.hydraulics ? program.At(t1).value : out.end.stroke;
}

double SimulatedController::Advance(double to_time, const SampleSink& sink) {
  Plant& plant = *plant_;
  for (;;) {
    CommandProgram program;
    daq::ControllerLimits limits;
    {
      std::lock_guard lock(mutex_);
      if (failed_) break;
      const double t1 = static_cast<double>(plant.state.index + chunk_samples_) / rate_;
      if (t1 > to_time + 1e-9 / rate_) break;
      program = program_;
      if (set_point_) limits = set_point_->limits;
      boundary_ = t1;  // a command from now on takes effect where this chunk ends
    }
    const double cpu_start = ThreadCpuSeconds();
    const PlantState saved = plant.state;
    Chunk chunk;
    std::uint16_t trip = 0;
    std::string trip_text;
    double trip_time = INFINITY;
    try {
      Integrate(plant, program, INFINITY, chunk);
      // The interlocks look at every sample taken with the hydraulics on; the first one beyond a
      // limit switches them off from that sample on, and the chunk is computed again so.
      const double force_limit = truth_.actuator.ideal ? 0.0 : truth_.actuator.force_limit;
      for (std::size_t i = 0; i < chunk.stroke.size() && !trip; ++i) {
        if (std::isnan(chunk.command[i])) continue;
        const double t = chunk.readings.start_time + static_cast<double>(i) / rate_;
        const double y = chunk.readings.stroke[i], f = chunk.readings.force[i];
        if (y < limits.stroke_min || y > limits.stroke_max) {
          trip = fault_bits::kStrokeLimit;
          trip_text = fmt::format("stroke {} outside the limits {} .. {}", Mm(y), Mm(limits.stroke_min),
                                  Mm(limits.stroke_max));
        } else if (f < limits.force_min || f > limits.force_max) {
          trip = fault_bits::kForceLimit;
          trip_text = fmt::format("force {:.0f} N outside the limits {:.0f} .. {:.0f} N", f, limits.force_min,
                                  limits.force_max);
        } else if (force_limit > 0 && std::abs(f) > force_limit) {
          trip = fault_bits::kForceLimit;
          trip_text = fmt::format("force {:.0f} N beyond the actuator's force limit {:.0f} N", f, force_limit);
        } else if (options_.following_error_limit > 0 &&
                   std::abs(chunk.command[i] - chunk.stroke[i]) > options_.following_error_limit) {
          trip = fault_bits::kFollowingError;
          trip_text = fmt::format("following error {} (command {}, stroke {}) beyond {}",
                                  Mm(chunk.command[i] - chunk.stroke[i]), Mm(chunk.command[i]), Mm(chunk.stroke[i]),
                                  Mm(options_.following_error_limit));
        }
        if (trip) trip_time = t;
      }
      if (trip) {
        // Up to the trip the samples are those the controller judged (a recomputation agrees to
        // IDA's tolerance, which can move a reading by an ADC count).
        const Chunk first = std::move(chunk);
        plant.state = saved;
        chunk = Chunk{};
        Integrate(plant, program, trip_time, chunk);
        const auto upto = static_cast<std::ptrdiff_t>(std::lround((trip_time - first.readings.start_time) * rate_)) + 1;
        for (auto [to, from] : {std::pair{&chunk.readings.stroke, &first.readings.stroke},
                                {&chunk.readings.force, &first.readings.force},
                                {&chunk.readings.pressure, &first.readings.pressure}, {&chunk.stroke, &first.stroke},
                                {&chunk.force, &first.force}, {&chunk.pressure, &first.pressure}})
          std::copy(from->begin(), from->begin() + upto, to->begin());
      }
    } catch (const std::exception& e) {  // whatever the plant threw: recorded as the device fault, then rethrown
      std::lock_guard lock(mutex_);
      failed_ = true;
      failure_ = e.what();
      fault_word_ |= fault_bits::kDevice;
      state_ = ControllerState::kFaulted;
      spdlog::error("simulated controller: the plant failed at t = {:.3f} s: {}", saved.index / rate_, e.what());
      throw;
    }
    {
      std::lock_guard lock(mutex_);
      snapshot_ = chunk.end;
      stroke_reading_ = chunk.readings.stroke.back();
      force_reading_ = chunk.readings.force.back();
      if (trip) {
        fault_word_ |= trip;
        state_ = ControllerState::kFaulted;
        program_ = CommandProgram::Locked(trip_time);
        spdlog::warn("simulated controller: interlock at t = {:.3f} s: {}; hydraulics off, fault latched", trip_time,
                     trip_text);
      }
      UpdateStateLocked(chunk.end.time);
      stats_.simulated_seconds = chunk.end.time;
      stats_.chunks += 1;
      stats_.ida_steps += chunk.ida_steps;
      stats_.recomputed_chunks += trip ? 1 : 0;
      stats_.knotted_chunks += chunk.smooth ? 0 : 1;
      stats_.cpu_seconds += ThreadCpuSeconds() - cpu_start;
    }
    if (sink) sink(chunk.readings);
  }
  return time();
}

void SimulatedController::UpdateStateLocked(double t) {
  if (program_.kind == CommandProgram::Kind::kSine) cycles_ = program_.Cycles(t);
  if (state_ == ControllerState::kStopping && t >= program_.End()) {
    // The ramp out is over: armed, holding the static position.
    state_ = ControllerState::kArmed;
    program_ = CommandProgram::Move(program_.End(), program_.mean, program_.mean, set_point_->static_rate);
  }
}

std::optional<std::string> SimulatedController::Apply(const daq::SetPoint& set_point) {
  if (set_point.mode != daq::ControlMode::kStroke)
    return std::string("force control is not simulated: the simulated servo loop closes on stroke only");
  std::lock_guard lock(mutex_);
  const bool moving = state_ == ControllerState::kRunning || state_ == ControllerState::kStopping;
  if (moving) {
    daq::SetPoint same_sine = set_point;
    same_sine.limits = set_point_->limits;
    if (!(same_sine == *set_point_))
      return fmt::format("set-point refused while {}: the sine cannot change mid-run (stop first); only the limits may",
                         daq::ToString(state_));
  }
  if (state_ == ControllerState::kArmed && program_.kind == CommandProgram::Kind::kMove) {
    // Armed: the command heads for the new static position from where it is.
    const double from = program_.At(boundary_).value;
    program_ = CommandProgram::Move(boundary_, from, set_point.static_position, set_point.static_rate);
  }
  set_point_ = set_point;
  spdlog::info("simulated controller: set-point at t = {:.3f} s: static {}, amplitude {} at {:g} Hz, ramp {} cycles, "
               "static rate {:.3g} mm/s",
               boundary_, Mm(set_point.static_position), Mm(set_point.amplitude), set_point.frequency,
               set_point.ramp_cycles, set_point.static_rate * 1e3);
  return std::nullopt;
}

std::optional<std::string> SimulatedController::Execute(ControllerCommand command) {
  std::lock_guard lock(mutex_);
  const std::string name(daq::ToString(command));
  if (failed_ && command != ControllerCommand::kDisarm)
    return fmt::format("{} refused: the simulated plant failed ({})", name, failure_);
  if (state_ == ControllerState::kFaulted && command != ControllerCommand::kDisarm &&
      command != ControllerCommand::kResetFaults)
    return fmt::format("{} refused: a fault is latched ({}; reset faults first)", name,
                       daq::FaultBitsText(fault_word_));
  const double b = boundary_;
  const std::string while_state = fmt::format(" while {}", daq::ToString(state_));
  switch (command) {
    case ControllerCommand::kArm:
      if (!set_point_) return std::string("arm refused: no set-point applied yet");
      if (state_ == ControllerState::kDisarmed) {
        // Hydraulics on: the command starts where the locked piston is and moves to the static level.
        program_ = CommandProgram::Move(b, snapshot_.stroke, set_point_->static_position, set_point_->static_rate);
        state_ = ControllerState::kArmed;
      } else if (state_ != ControllerState::kArmed) {
        return "arm refused" + while_state;
      }
      break;
    case ControllerCommand::kRun:
      if (state_ != ControllerState::kArmed)
        return fmt::format("run refused: the controller is not armed (it is {})", daq::ToString(state_));
      if (program_.kind != CommandProgram::Kind::kMove || program_.End() > b + 1e-9) {
        const double to_go = std::abs(program_.to - program_.At(b).value);
        return fmt::format("run refused: still moving to the static position ({} to go at {:.3g} mm/s)", Mm(to_go),
                           program_.rate * 1e3);
      }
      program_ = CommandProgram::Sine(b, set_point_->static_position, set_point_->amplitude, set_point_->frequency,
                                      set_point_->ramp_cycles);
      state_ = ControllerState::kRunning;
      cycles_ = 0;
      break;
    case ControllerCommand::kStop:
      if (state_ == ControllerState::kRunning) {
        program_.stop_at = program_.NextCycleBoundary(b);
        state_ = ControllerState::kStopping;
      } else if (state_ != ControllerState::kStopping && state_ != ControllerState::kArmed) {
        return "stop refused" + while_state;
      }
      break;
    case ControllerCommand::kDisarm:
      if (state_ != ControllerState::kDisarmed && state_ != ControllerState::kFaulted)
        program_ = CommandProgram::Locked(b);
      if (state_ != ControllerState::kFaulted) state_ = ControllerState::kDisarmed;
      break;
    case ControllerCommand::kResetFaults:
      fault_word_ = 0;
      if (state_ == ControllerState::kFaulted) state_ = ControllerState::kDisarmed;
      break;
  }
  spdlog::info("simulated controller: {} at t = {:.3f} s: {}", name, b, daq::ToString(state_));
  return std::nullopt;
}

daq::ControllerStatus SimulatedController::StatusLocked() const {
  daq::ControllerStatus s;
  s.state = state_;
  s.mode = daq::ControlMode::kStroke;
  s.fault_word = fault_word_;
  s.stroke = stroke_reading_;
  s.force = force_reading_;
  s.cycles = cycles_;
  const double t = snapshot_.time;
  s.time_ms = static_cast<std::uint32_t>(static_cast<std::uint64_t>(std::llround(t * 1e3)) & 0xFFFFFFFFu);
  const bool hydraulics = state_ == ControllerState::kArmed || state_ == ControllerState::kRunning ||
                          state_ == ControllerState::kStopping;
  // The command a chunk under way has not reached yet is where that program starts.
  const double at = std::max(t, program_.start);
  s.command = hydraulics ? program_.At(at).value : snapshot_.stroke;
  if (hydraulics) {
    s.status_word |= status_bits::kHydraulicsOn;
    if (program_.kind == CommandProgram::Kind::kMove) {
      s.status_word |= at >= program_.End() ? status_bits::kAtStatic : status_bits::kRamping;
    } else if (program_.kind == CommandProgram::Kind::kSine) {
      const bool started = t >= program_.start;
      s.status_word |= started && program_.Envelope(t) >= 1.0 ? status_bits::kFullAmplitude : status_bits::kRamping;
    }
  }
  return s;
}

daq::ControllerStatus SimulatedController::Status() {
  std::lock_guard lock(mutex_);
  return StatusLocked();
}

double SimulatedController::time() const {
  std::lock_guard lock(mutex_);
  return snapshot_.time;
}

PlantSnapshot SimulatedController::plant() const {
  std::lock_guard lock(mutex_);
  return snapshot_;
}

SimulatedControllerStats SimulatedController::stats() const {
  std::lock_guard lock(mutex_);
  return stats_;
}

CommandProgram SimulatedController::program() const {
  std::lock_guard lock(mutex_);
  return program_;
}

}  // namespace strut::sim
