#include "strut/rig/safety.h"

#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <set>

#include "strut/daq/session.h"
#include "strut/ident/fit_record.h"
#include "strut/ident/periodic.h"
#include "strut/daq/toml_reader.h"

namespace strut::rig {

std::string_view ToString(SafetyAction action) {
  switch (action) {
    case SafetyAction::kIndicate:
      return "indicate";
    case SafetyAction::kHold:
      return "hold";
    case SafetyAction::kStop:
      return "stop";
    case SafetyAction::kInterlock:
      return "interlock";
  }
  return "unknown";
}

std::optional<SafetyAction> SafetyActionFrom(std::string_view text) {
  for (SafetyAction a : {SafetyAction::kIndicate, SafetyAction::kHold, SafetyAction::kStop, SafetyAction::kInterlock})
    if (ToString(a) == text) return a;
  return std::nullopt;
}

bool SafetyConfig::IsValid(std::string* error) const {
  auto fail = [&](std::string m) {
    if (error) *error = std::move(m);
    return false;
  };
  const auto limit = [&](const char* name, const ChannelLimit& l) {
    if (!std::isfinite(l.lower) || !std::isfinite(l.upper) || !(l.lower < l.upper))
      return fail(fmt::format("[{}] lower {} must be below upper {} (both finite)", name, l.lower, l.upper));
    if (l.persistence < 1 || l.persistence > 100000)
      return fail(fmt::format("[{}] persistence {} is outside 1..100000 samples", name, l.persistence));
    return true;
  };
  if (!limit("stroke", stroke) || !limit("force", force) || !limit("pressure", pressure)) return false;
  if (!(following.max_error > 0.0 && std::isfinite(following.max_error)) || following.persistence < 1)
    return fail(fmt::format("[following_error] max_error {} must be positive and persistence {} >= 1", following.max_error,
                            following.persistence));
  if (!(under_peak.fraction > 0.0 && under_peak.fraction <= 1.0) || under_peak.cycles < 1)
    return fail(fmt::format("[under_peak] fraction {} must be in (0, 1] and cycles {} >= 1", under_peak.fraction,
                            under_peak.cycles));
  if (stale.timeout.count() < 1) return fail("[stale] timeout must be at least 1 ms");
  if (lag.max_lag && lag.max_lag->count() < 1) return fail("[lag] max_lag must be at least 1 ms");
  if (heartbeat.controller_timeout.count() < 1) return fail("[heartbeat] controller_timeout must be at least 1 ms");
  if (heartbeat.watchdog.count() < 0 || heartbeat.watchdog.count() > 65535)
    return fail(fmt::format("[heartbeat] watchdog {} ms is outside 0..65535 ms", heartbeat.watchdog.count()));
  for (auto [name, v] : {std::pair{"max_velocity", actuator.max_velocity}, {"piston_area", actuator.piston_area},
                         {"max_flow", actuator.max_flow}}) {
    if (!(v > 0.0 && std::isfinite(v))) return fail(fmt::format("[actuator] {} = {} must be positive", name, v));
  }
  if (!(controller.stroke_min < controller.stroke_max) || !(controller.force_min < controller.force_max))
    return fail("[controller] limits must be ordered (min below max)");
  return true;
}

namespace {

// The limits file's sections over the shared TOML reading; a key absent keeps its default.
class Reader {
 public:
  Reader(const toml::table& root, const daq::TomlReader<SafetyError>& reader) : root_(root), toml_(reader) {}

  [[noreturn]] void Fail(const toml::node& n, const std::string& what) const { toml_.Fail(n, what); }

  // Visits a section, refusing keys it does not know.
  template <typename F>
  void Section(const char* name, std::initializer_list<const char*> keys, F&& read) {
    seen_.insert(name);
    const toml::node* node = root_.get(name);
    if (!node) return;
    const toml::table& t = toml_.Table(*node, "", name);
    toml_.RefuseUnknown(t, Where(name), keys);
    read(t);
  }

  // Visits a detector's section (`keys` are all its keys): its `enabled` switch and its `action`
  // here, the detector's own settings in `read`.
  template <typename Settings, typename F>
  void Detector(const char* name, std::initializer_list<const char*> keys, Settings& settings, F&& read) {
    Section(name, keys, [&](const toml::table& t) {
      Bool(t, name, "enabled", settings.enabled);
      read(t);
      Action(t, name, settings.action);
    });
  }

  void Number(const toml::table& t, const char* section, const char* key, double& out) const {
    if (const auto v = toml_.Number(t, Where(section), key)) out = *v;
  }
  void Integer(const toml::table& t, const char* section, const char* key, int& out) const {
    if (const auto v = toml_.Integer(t, Where(section), key)) out = static_cast<int>(*v);
  }
  void Bool(const toml::table& t, const char* section, const char* key, bool& out) const {
    if (const auto v = toml_.Bool(t, Where(section), key)) out = *v;
  }
  void Millis(const toml::table& t, const char* section, const char* key, std::chrono::milliseconds& out) const {
    double seconds = out.count() * 1e-3;
    Number(t, section, key, seconds);
    out = std::chrono::milliseconds(std::llround(seconds * 1e3));
  }
  void Action(const toml::table& t, const char* section, SafetyAction& out) const {
    const toml::node* n = t.get("action");
    if (!n) return;
    const auto text = n->value<std::string>();
    const auto action = text ? SafetyActionFrom(*text) : std::nullopt;
    if (!action) Fail(*n, fmt::format("[{}] action must be \"indicate\", \"hold\", \"stop\" or \"interlock\"", section));
    out = *action;
  }
  void Limit(const char* section, ChannelLimit& l) {
    Detector(section, {"enabled", "lower", "upper", "persistence", "action"}, l, [&](const toml::table& t) {
      Number(t, section, "lower", l.lower);
      Number(t, section, "upper", l.upper);
      Integer(t, section, "persistence", l.persistence);
    });
  }
  void RefuseUnknownSections() const {
    for (auto&& [k, v] : root_) {
      if (!seen_.count(std::string(k.str())))
        Fail(v, fmt::format("unknown section '{}' (known: stroke, force, pressure, following_error, under_peak, stale, "
                            "lag, heartbeat, actuator, controller)",
                            k.str()));
    }
  }

 private:
  static std::string Where(const char* section) { return daq::TomlReader<SafetyError>::In(section); }

  const toml::table& root_;
  const daq::TomlReader<SafetyError>& toml_;
  std::set<std::string> seen_;
};

}  // namespace

SafetyConfig ParseSafetyConfig(std::string_view text, const std::string& source) {
  const daq::TomlReader<SafetyError> reader(source);
  const toml::table root = reader.Parse(text);
  SafetyConfig c;
  Reader r(root, reader);
  r.Limit("stroke", c.stroke);
  r.Limit("force", c.force);
  r.Limit("pressure", c.pressure);
  r.Detector("following_error", {"enabled", "max_error", "persistence", "action"}, c.following,
             [&](const toml::table& t) {
               r.Number(t, "following_error", "max_error", c.following.max_error);
               r.Integer(t, "following_error", "persistence", c.following.persistence);
             });
  r.Detector("under_peak", {"enabled", "fraction", "cycles", "action"}, c.under_peak, [&](const toml::table& t) {
    r.Number(t, "under_peak", "fraction", c.under_peak.fraction);
    r.Integer(t, "under_peak", "cycles", c.under_peak.cycles);
  });
  r.Detector("stale", {"enabled", "timeout", "action"}, c.stale,
             [&](const toml::table& t) { r.Millis(t, "stale", "timeout", c.stale.timeout); });
  r.Detector("lag", {"enabled", "max_lag", "action"}, c.lag, [&](const toml::table& t) {
    if (!t.contains("max_lag")) return;
    std::chrono::milliseconds max_lag{0};
    r.Millis(t, "lag", "max_lag", max_lag);
    c.lag.max_lag = max_lag;
  });
  r.Detector("heartbeat", {"enabled", "controller_timeout", "watchdog", "action"}, c.heartbeat,
             [&](const toml::table& t) {
               r.Millis(t, "heartbeat", "controller_timeout", c.heartbeat.controller_timeout);
               r.Millis(t, "heartbeat", "watchdog", c.heartbeat.watchdog);
             });
  r.Section("actuator", {"max_velocity", "piston_area", "max_flow"}, [&](const toml::table& t) {
    r.Number(t, "actuator", "max_velocity", c.actuator.max_velocity);
    r.Number(t, "actuator", "piston_area", c.actuator.piston_area);
    r.Number(t, "actuator", "max_flow", c.actuator.max_flow);
  });
  r.Section("controller", {"stroke_min", "stroke_max", "force_min", "force_max"}, [&](const toml::table& t) {
    r.Number(t, "controller", "stroke_min", c.controller.stroke_min);
    r.Number(t, "controller", "stroke_max", c.controller.stroke_max);
    r.Number(t, "controller", "force_min", c.controller.force_min);
    r.Number(t, "controller", "force_max", c.controller.force_max);
  });
  r.RefuseUnknownSections();
  std::string error;
  if (!c.IsValid(&error)) throw SafetyError(fmt::format("{}: {}", source, error));
  return c;
}

SafetyConfig ReadSafetyConfig(const std::string& path) {
  return ParseSafetyConfig(daq::TomlReader<SafetyError>::ReadFile(path, "the limits file"), path);
}

// ---------------------------------------------------------------------------------------------
// Run-time detectors

SafetyMonitor::SafetyMonitor(SafetyConfig config, const std::vector<std::string>& channels, double stream_speed)
    : config_(std::move(config)), stream_speed_(stream_speed) {
  std::string error;
  if (!config_.IsValid(&error)) throw std::invalid_argument("safety config: " + error);
  if (!(stream_speed > 0.0 && std::isfinite(stream_speed)))
    throw std::invalid_argument(fmt::format("safety monitor: stream speed {} must be positive", stream_speed));
  for (std::size_t k = 0; k < channels.size(); ++k) {
    if (channels[k] == "stroke")
      limited_.push_back({k, "stroke-limit", "m", &SafetyConfig::stroke, &SafetyMonitor::stroke_, &Margins::stroke});
    if (channels[k] == "force")
      limited_.push_back({k, "force-limit", "N", &SafetyConfig::force, &SafetyMonitor::force_, &Margins::force});
    if (channels[k] == "pressure")
      limited_.push_back(
          {k, "pressure-limit", "Pa", &SafetyConfig::pressure, &SafetyMonitor::pressure_, &Margins::pressure});
  }
}

void SafetyMonitor::Arm(std::int64_t now_ns) {
  last_sample_ns_ = now_ns;
  heartbeat_changed_ns_ = now_ns;
  last_heartbeat_.reset();
}

void SafetyMonitor::Reset(std::int64_t now_ns) {
  stroke_ = force_ = pressure_ = following_ = {};
  stale_latched_ = heartbeat_latched_ = fault_latched_ = under_peak_latched_ = lag_latched_ = false;
  largest_lag_ns_ = 0;
  under_peak_count_ = 0;
  Arm(now_ns);
}

namespace {
// Fraction of the band [lower, upper] between value and the nearer limit, scaled so the middle is 1.
double Margin(double value, double lower, double upper) {
  const double half = 0.5 * (upper - lower);
  return std::min(value - lower, upper - value) / half;
}
}  // namespace

std::optional<Trip> SafetyMonitor::CheckLimit(const char* detector, const char* unit, const ChannelLimit& l,
                                              LimitState& s, double v, std::int64_t t) {
  if (!l.enabled || s.latched) return std::nullopt;
  if (v >= l.lower && v <= l.upper) {
    s.count = 0;
    return std::nullopt;
  }
  if (++s.count < l.persistence) return std::nullopt;
  s.latched = true;
  const std::string channel(detector, std::string_view(detector).find('-'));
  return Trip{detector, l.action, t,
              fmt::format("{} {:.6g} {} {} the limit {:.6g} {} for {} samples", channel, v, unit,
                          v > l.upper ? "above" : "below", v > l.upper ? l.upper : l.lower, unit, s.count)};
}

std::vector<Trip> SafetyMonitor::CheckBlock(const daq::AcquiredBlock& block) {
  std::vector<Trip> trips;
  if (block.empty()) return trips;
  // Silence is judged by the samples' arrival; a stream that arrives but behind its own clock is
  // the lag detector's (CheckLag), which says which of the two a lagging simulated rig is.
  last_sample_ns_ = std::max(last_sample_ns_, block.last_frame_ns > 0 ? block.last_frame_ns : block.time_ns.back());
  if (auto trip = CheckLag(block)) trips.push_back(std::move(*trip));
  for (const LimitedChannel& c : limited_) {
    if (c.k >= block.values.size()) continue;
    const ChannelLimit& l = config_.*c.limit;
    LimitState& s = this->*c.state;
    double& margin = margins_.*c.margin;
    const std::vector<double>& v = block.values[c.k];
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (l.enabled) margin = std::min(margin, Margin(v[i], l.lower, l.upper));  // no limit, no margin to it
      if (auto trip = CheckLimit(c.detector, c.unit, l, s, v[i], block.time_ns[i])) trips.push_back(std::move(*trip));
    }
  }
  return trips;
}

std::chrono::milliseconds SafetyMonitor::max_lag() const {
  if (config_.lag.max_lag) return *config_.lag.max_lag;
  return std::chrono::milliseconds(stream_speed_ == 1.0 ? 500 : 3000);
}

std::optional<Trip> SafetyMonitor::CheckLag(const daq::AcquiredBlock& block) {
  if (block.last_frame_ns <= 0) return std::nullopt;  // a source without arrival times (replay, tests)
  const std::int64_t lag = block.last_frame_ns - block.time_ns.back();
  largest_lag_ns_ = std::max(largest_lag_ns_, lag);
  const std::chrono::milliseconds limit = max_lag();
  if (!config_.lag.enabled || lag_latched_ || lag < std::chrono::nanoseconds(limit).count()) return std::nullopt;
  lag_latched_ = true;
  const std::string why =
      stream_speed_ != 1.0
          ? fmt::format("the simulated rig cannot hold {:g}x real time on this machine (it computes its samples slower "
                        "than they are due); run it again at a lower --speed (--resume goes on)",
                        stream_speed_)
          : "the module's clock runs behind the host's or its frames are held up on the way";
  return Trip{"stream-lag", config_.lag.action, block.last_frame_ns,
              fmt::format("the samples arrive {} ms behind their own clock (limit {} ms): {}", lag / 1'000'000,
                          limit.count(), why)};
}

std::optional<Trip> SafetyMonitor::CheckStale(std::int64_t now_ns) {
  if (!config_.stale.enabled || stale_latched_) return std::nullopt;
  const std::int64_t silent = now_ns - last_sample_ns_;
  if (silent < std::chrono::nanoseconds(config_.stale.timeout).count()) return std::nullopt;
  stale_latched_ = true;
  return Trip{"stale-data", config_.stale.action, now_ns,
              fmt::format("no sample from the acquisition for {} ms (limit {} ms)", silent / 1'000'000,
                          config_.stale.timeout.count())};
}

std::vector<Trip> SafetyMonitor::CheckStatus(const daq::ControllerStatus& status, std::int64_t now_ns) {
  std::vector<Trip> trips;
  if (status.faulted() && !fault_latched_) {
    fault_latched_ = true;
    // The controller's own interlock already acted; strut follows with the same.
    trips.push_back({"controller-fault", SafetyAction::kInterlock, now_ns,
                     fmt::format("the controller latched faults 0x{:04x} ({}), state {}", status.fault_word,
                                 daq::FaultBitsText(status.fault_word), daq::ToString(status.state))});
  }
  if (config_.heartbeat.enabled && !heartbeat_latched_) {
    if (!last_heartbeat_ || *last_heartbeat_ != status.heartbeat) {
      last_heartbeat_ = status.heartbeat;
      heartbeat_changed_ns_ = now_ns;
    } else if (now_ns - heartbeat_changed_ns_ >= std::chrono::nanoseconds(config_.heartbeat.controller_timeout).count()) {
      heartbeat_latched_ = true;
      trips.push_back({"controller-heartbeat", config_.heartbeat.action, now_ns,
                       fmt::format("the controller's heartbeat counter stayed at {} for {} ms (limit {} ms)",
                                   status.heartbeat, (now_ns - heartbeat_changed_ns_) / 1'000'000,
                                   config_.heartbeat.controller_timeout.count())});
    }
  }
  if (config_.following.enabled && status.mode == daq::ControlMode::kStroke &&
      status.state != daq::ControllerState::kDisarmed && status.state != daq::ControllerState::kFaulted) {
    const double error = status.command - status.stroke;
    margins_.following = std::min(margins_.following, 1.0 - std::abs(error) / config_.following.max_error);
    if (!following_.latched) {
      if (std::abs(error) <= config_.following.max_error) {
        following_.count = 0;
      } else if (++following_.count >= config_.following.persistence) {
        following_.latched = true;
        trips.push_back({"following-error", config_.following.action, now_ns,
                         fmt::format("command {:.6g} m minus stroke {:.6g} m = {:.6g} m beyond {:.6g} m for {} reads",
                                     status.command, status.stroke, error, config_.following.max_error,
                                     following_.count)});
      }
    }
  }
  return trips;
}

std::optional<Trip> SafetyMonitor::CheckCycle(const CycleSummary& cycle, double commanded, std::int64_t now_ns) {
  if (!config_.under_peak.enabled || under_peak_latched_ || !(commanded > 0.0)) return std::nullopt;
  const double reached = cycle.stroke_amplitude();
  if (reached >= config_.under_peak.fraction * commanded) {
    under_peak_count_ = 0;
    return std::nullopt;
  }
  if (++under_peak_count_ < config_.under_peak.cycles) return std::nullopt;
  under_peak_latched_ = true;
  return Trip{"under-peak", config_.under_peak.action, now_ns,
              fmt::format("stroke amplitude {:.6g} m is {:.1f} % of the commanded {:.6g} m for {} cycles (limit {:.0f} %)",
                          reached, 100.0 * reached / commanded, commanded, under_peak_count_,
                          100.0 * config_.under_peak.fraction)};
}

Margins SafetyMonitor::TakeMargins() { return std::exchange(margins_, Margins{}); }

// ---------------------------------------------------------------------------------------------
// The matrix check

ResponsePredictor FitPredictor(const ident::FitRecord& fit, int points) {
  auto solver = std::make_shared<ident::PeriodicSolver>(fit.model);
  auto theta = std::make_shared<std::vector<double>>(fit.parameters.values());
  const std::string source = fit.source;
  return [solver, theta, source, points](const MatrixEntry& e) {
    PredictedResponse r;
    try {
      const auto input = ident::PeriodicInput::Sine(e.frequency, e.static_position, e.amplitude, points);
      const ident::PeriodicSolution s = solver->Solve(input, *theta);
      const auto row = [&](const char* name) -> std::optional<Eigen::VectorXd> {
        for (std::size_t c = 0; c < s.channels.size(); ++c)
          if (s.channels[c] == name) return Eigen::VectorXd(s.outputs.row(static_cast<Eigen::Index>(c)).transpose());
        return std::nullopt;
      };
      const auto force = row("force");
      if (!force) throw SafetyError(fmt::format("the model of {} predicts no force", source));
      r.force_min = force->minCoeff();
      r.force_max = force->maxCoeff();
      if (const auto p = row("pressure")) {
        r.pressure_min = p->minCoeff();
        r.pressure_max = p->maxCoeff();
      } else {
        r.pressure_min = r.pressure_max = std::nan("");
      }
    } catch (const ident::PeriodicSolverError& ex) {
      throw SafetyError(fmt::format("experiment '{}': the fit {} has no periodic response to predict: {}", e.label,
                                    source, ex.what()));
    }
    return r;
  };
}

std::vector<std::string> CheckMatrix(const std::vector<MatrixEntry>& matrix, const SafetyConfig& c, double sample_rate,
                                     const ResponsePredictor& predictor) {
  std::vector<std::string> refusals;
  const double lowest = std::max(c.stroke.enabled ? c.stroke.lower : -1e300, c.controller.stroke_min);
  const double highest = std::min(c.stroke.enabled ? c.stroke.upper : 1e300, c.controller.stroke_max);
  for (const MatrixEntry& e : matrix) {
    const auto refuse = [&](std::string what) { refusals.push_back(fmt::format("experiment '{}': {}", e.label, what)); };
    if (!(e.frequency > 0.0) || !(e.amplitude >= 0.0) || !std::isfinite(e.static_position)) {
      refuse(fmt::format("frequency {} Hz, amplitude {} m, static position {} m are no sine", e.frequency, e.amplitude,
                         e.static_position));
      continue;
    }
    const double low = e.static_position - e.amplitude, high = e.static_position + e.amplitude;
    if (low < lowest || high > highest)
      refuse(fmt::format("stroke {:.4g} .. {:.4g} m leaves the stroke limit {:.4g} .. {:.4g} m", low, high, lowest, highest));
    const double velocity = 2.0 * std::numbers::pi * e.frequency * e.amplitude;
    if (velocity > c.actuator.max_velocity)
      refuse(fmt::format("peak velocity 2 pi f A = {:.4g} m/s exceeds the velocity limit {:.4g} m/s", velocity,
                         c.actuator.max_velocity));
    const double flow = c.actuator.piston_area * velocity;
    if (flow > c.actuator.max_flow)
      refuse(fmt::format("actuator flow {:.4g} m^3/s ({:.1f} l/min: piston area {:.4g} m^2 x {:.4g} m/s) exceeds the "
                         "supply's {:.4g} m^3/s ({:.1f} l/min)",
                         flow, flow * 6e4, c.actuator.piston_area, velocity, c.actuator.max_flow, c.actuator.max_flow * 6e4));
    if (!daq::WholeSamplesPerPeriod(sample_rate, e.frequency, 16))
      refuse(fmt::format("{} Hz sampled at {} Hz is not a whole number (>= 16) of samples per period", e.frequency,
                         sample_rate));
    if (predictor) {
      const PredictedResponse p = predictor(e);
      const double f_low = std::max(c.force.enabled ? c.force.lower : -1e300, c.controller.force_min);
      const double f_high = std::min(c.force.enabled ? c.force.upper : 1e300, c.controller.force_max);
      if (p.force_min < f_low || p.force_max > f_high)
        refuse(fmt::format("predicted force {:.4g} .. {:.4g} N leaves the force limit {:.4g} .. {:.4g} N", p.force_min,
                           p.force_max, f_low, f_high));
      if (c.pressure.enabled && std::isfinite(p.pressure_max)) {
        // The models give absolute pressure; the limit applies to the acquired (gauge) reading.
        const double low_p = p.pressure_min - daq::kGaugeReferencePa, high_p = p.pressure_max - daq::kGaugeReferencePa;
        if (low_p < c.pressure.lower || high_p > c.pressure.upper)
          refuse(fmt::format("predicted pressure {:.4g} .. {:.4g} Pa (gauge) leaves the pressure limit {:.4g} .. {:.4g} Pa",
                             low_p, high_p, c.pressure.lower, c.pressure.upper));
      }
    }
  }
  return refusals;
}

MatrixPlan DecisiveTestPlan(const ident::DecisiveTest& test) {
  MatrixPlan plan;
  plan.source = "<the decisive test>";
  plan.sample_rate = test.sample_rate;
  plan.periods = test.periods;
  plan.experiments.push_back({"decide", "decide", test.frequency, test.static_position, test.amplitude});
  return plan;
}

ident::TestSpace DecisiveTestSpace(const std::vector<ident::ExperimentData>& recorded, const SafetyConfig& c) {
  ident::TestSpace space = ident::TestSpaceOf(recorded);
  const double lowest = std::max({c.stroke.enabled ? c.stroke.lower : -1e300, c.controller.stroke_min, 0.0});
  const double highest = std::min({c.stroke.enabled ? c.stroke.upper : 1e300, c.controller.stroke_max, ident::kDamperStroke});
  space.stroke_min = lowest + kDecisiveTestStrokeMargin;
  space.stroke_max = highest - kDecisiveTestStrokeMargin;
  // Slower than the matrix too: near-isothermal cycles, where thermal explanations part from gas-law ones.
  for (const double f : kDecisiveTestSlowFrequencies)
    if (daq::WholeSamplesPerPeriod(space.sample_rate, f, 16) &&
        std::find(space.frequencies.begin(), space.frequencies.end(), f) == space.frequencies.end())
      space.frequencies.insert(space.frequencies.begin(), f);
  space.max_rate = std::min(c.actuator.max_velocity, c.actuator.max_flow / c.actuator.piston_area) * (1 - kDecisiveTestMargin);
  const double f_high = std::min(c.force.enabled ? c.force.upper : 1e300, c.controller.force_max);
  space.max_force = f_high * (1 - kDecisiveTestMargin);
  if (c.pressure.enabled)
    space.max_pressure = c.pressure.upper - kDecisiveTestMargin * (c.pressure.upper - c.pressure.lower) + daq::kGaugeReferencePa;
  const double smallest = *std::min_element(space.amplitudes.begin(), space.amplitudes.end());
  space.static_positions.clear();
  for (int k = 0; k < 9; ++k)
    space.static_positions.push_back(space.stroke_min + smallest + (space.stroke_max - space.stroke_min - 2 * smallest) * k / 8.0);
  return space;
}

}  // namespace strut::rig
