#include "strut/rig/steady_state.h"

#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace strut::rig {

bool SteadyStateTolerances::IsValid(std::string* error) const {
  auto fail = [&](std::string m) {
    if (error) *error = std::move(m);
    return false;
  };
  for (auto [name, v] : {std::pair{"force", force}, {"stroke", stroke}, {"pressure", pressure}}) {
    if (!(v > 0.0 && v < 1.0)) return fail(fmt::format("steady_state.{} = {} is outside (0, 1)", name, v));
  }
  if (!(pressure_floor > 0.0 && std::isfinite(pressure_floor)))
    return fail(fmt::format("steady_state.pressure_floor = {} must be positive", pressure_floor));
  if (consecutive < 1 || consecutive > 100) return fail(fmt::format("steady_state.consecutive = {} is outside 1..100", consecutive));
  if (max_cycles < consecutive + 1 || max_cycles > 100000)
    return fail(fmt::format("steady_state.max_cycles = {} is outside {}..100000", max_cycles, consecutive + 1));
  if (!(time_limit > 0.0 && std::isfinite(time_limit)))
    return fail(fmt::format("steady_state.time_limit = {} s must be positive", time_limit));
  if (!(drift_window >= 0.0 && drift_window < time_limit))
    return fail(fmt::format("steady_state.drift_window = {} s is outside 0 .. time_limit ({} s)", drift_window, time_limit));
  if (!(pressure_drift > 0.0 && pressure_drift < 1.0))
    return fail(fmt::format("steady_state.pressure_drift = {} is outside (0, 1)", pressure_drift));
  return true;
}

double CycleChange::worst_ratio(const SteadyStateTolerances& t) const {
  double worst = std::max(stroke / t.stroke, force / t.force);
  if (std::isfinite(pressure)) worst = std::max(worst, pressure / t.pressure);
  return worst;
}

CycleChange ChangeBetween(const CycleSummary& a, const CycleSummary& b, const SteadyStateTolerances& t) {
  const auto relative = [](double d, double reference) {
    return reference > 0.0 ? d / reference : (d == 0.0 ? 0.0 : std::numeric_limits<double>::infinity());
  };
  CycleChange c;
  c.stroke = relative(std::max(std::abs(b.stroke_max - a.stroke_max), std::abs(b.stroke_min - a.stroke_min)),
                      std::max(b.stroke_max - b.stroke_min, 1e-9));
  c.force = relative(std::max(std::abs(b.force_max - a.force_max), std::abs(b.force_min - a.force_min)),
                     std::max(b.force_range(), 1e-6));
  if (std::isnan(a.pressure_mean) || std::isnan(b.pressure_mean)) {
    c.pressure = std::numeric_limits<double>::quiet_NaN();
  } else {
    c.pressure = relative(std::abs(b.pressure_mean - a.pressure_mean),
                          std::max(std::abs(b.pressure_mean), t.pressure_floor));
  }
  return c;
}

SteadyStateDetector::SteadyStateDetector(SteadyStateTolerances tolerances) : tolerances_(tolerances) {
  std::string error;
  if (!tolerances_.IsValid(&error)) throw std::invalid_argument(error);
  verdict_.measure = std::numeric_limits<double>::infinity();
}

const SteadyStateVerdict& SteadyStateDetector::Add(const CycleSummary& cycle) {
  cycles_.push_back(cycle);
  if (verdict_.done()) return verdict_;
  verdict_.cycles = static_cast<long>(cycles_.size());
  if (cycles_.size() >= 2) {
    verdict_.last_change = ChangeBetween(cycles_[cycles_.size() - 2], cycle, tolerances_);
    verdict_.measure = verdict_.last_change.worst_ratio(tolerances_);
    verdict_.agreeing = verdict_.measure < 1.0 ? verdict_.agreeing + 1 : 0;
  }
  const double elapsed = (cycle.end_ns - cycles_.front().start_ns) * 1e-9;
  verdict_.elapsed = elapsed;
  verdict_.drift = Drift();
  if (verdict_.agreeing >= tolerances_.consecutive && elapsed >= tolerances_.drift_window && !Drifting()) {
    verdict_.steady = true;
    verdict_.steady_at = cycle.cycle;
    return verdict_;
  }
  if (verdict_.cycles >= tolerances_.max_cycles || elapsed >= tolerances_.time_limit) verdict_.timed_out = true;
  return verdict_;
}

double SteadyStateDetector::Drift() const {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const CycleSummary& last = cycles_.back();
  if (tolerances_.drift_window <= 0.0 || std::isnan(last.pressure_mean)) return nan;
  for (auto it = cycles_.rbegin() + 1; it != cycles_.rend(); ++it)
    if ((last.end_ns - it->end_ns) * 1e-9 >= tolerances_.drift_window) {
      const double reference = std::max(std::abs(last.pressure_mean), tolerances_.pressure_floor);
      return std::abs(last.pressure_mean - it->pressure_mean) / reference;
    }
  return nan;
}

bool SteadyStateDetector::Drifting() const {
  const CycleSummary& last = cycles_.back();
  if (tolerances_.drift_window <= 0.0 || std::isnan(last.pressure_mean)) return false;
  const CycleSummary* earlier = nullptr;
  for (auto it = cycles_.rbegin() + 1; it != cycles_.rend(); ++it)
    if ((last.end_ns - it->end_ns) * 1e-9 >= tolerances_.drift_window) {
      earlier = &*it;
      break;
    }
  if (!earlier) return true;
  const double reference = std::max(std::abs(last.pressure_mean), tolerances_.pressure_floor);
  return std::abs(last.pressure_mean - earlier->pressure_mean) > tolerances_.pressure_drift * reference;
}

SteadyStateVerdict DetectSteadyState(std::span<const CycleSummary> cycles, const SteadyStateTolerances& tolerances) {
  SteadyStateDetector detector(tolerances);
  for (const CycleSummary& c : cycles) {
    if (detector.Add(c).done()) break;
  }
  return detector.verdict();
}

CycleSummariser::CycleSummariser(long samples_per_cycle) : samples_per_cycle_(samples_per_cycle) {
  if (samples_per_cycle < 2) throw std::invalid_argument(fmt::format("{} samples per cycle: need at least 2", samples_per_cycle));
}

void CycleSummariser::Restart() { filled_ = 0; }

std::vector<CycleSummary> CycleSummariser::Add(std::span<const std::int64_t> t, std::span<const double> stroke,
                                               std::span<const double> force, std::span<const double> pressure) {
  if (stroke.size() != t.size() || force.size() != t.size() || (!pressure.empty() && pressure.size() != t.size()))
    throw std::invalid_argument("CycleSummariser::Add: channels of different lengths");
  std::vector<CycleSummary> done;
  for (std::size_t i = 0; i < t.size(); ++i) {
    if (filled_ == 0) {
      current_ = CycleSummary{};
      current_.cycle = next_cycle_;
      current_.start_ns = t[i];
      current_.stroke_min = current_.stroke_max = stroke[i];
      current_.force_min = current_.force_max = force[i];
      pressure_sum_ = 0.0;
      has_pressure_ = !pressure.empty();
    }
    current_.end_ns = t[i];
    current_.stroke_min = std::min(current_.stroke_min, stroke[i]);
    current_.stroke_max = std::max(current_.stroke_max, stroke[i]);
    current_.force_min = std::min(current_.force_min, force[i]);
    current_.force_max = std::max(current_.force_max, force[i]);
    if (!pressure.empty()) pressure_sum_ += pressure[i];
    if (++filled_ == samples_per_cycle_) {
      current_.pressure_mean = has_pressure_ ? pressure_sum_ / static_cast<double>(samples_per_cycle_)
                                             : std::numeric_limits<double>::quiet_NaN();
      done.push_back(current_);
      ++next_cycle_;
      filled_ = 0;
    }
  }
  return done;
}

std::vector<CycleSummary> SummariseExperiment(const daq::Experiment& e) {
  if (e.kind != daq::ExperimentKind::kPeriodic)
    throw daq::SessionError(fmt::format("experiment '{}': not periodic, no cycles to summarise", e.label));
  const auto n = daq::WholeSamplesPerPeriod(e.sample_rate, e.frequency, 2);
  if (!n)
    throw daq::SessionError(fmt::format("experiment '{}': {} Hz at {} Hz is no whole number of samples per period",
                                        e.label, e.frequency, e.sample_rate));
  std::vector<std::int64_t> t(e.time.size());
  for (std::size_t i = 0; i < t.size(); ++i) t[i] = std::llround(e.time[i] * 1e9);
  const daq::Channel* pressure = e.find_channel("pressure");
  CycleSummariser s(*n);
  return s.Add(t, e.channel("stroke").samples, e.channel("force").samples,
               pressure ? std::span<const double>(pressure->samples) : std::span<const double>());
}

daq::MetadataGroup CyclesGroup(const std::string& name, std::span<const CycleSummary> cycles,
                               const SteadyStateVerdict& verdict, const SteadyStateTolerances& t) {
  daq::MetadataGroup g{name, {}, {}};
  g.attributes["steady"] = static_cast<long long>(verdict.steady);
  g.attributes["timed_out"] = static_cast<long long>(verdict.timed_out);
  g.attributes["steady_at"] = static_cast<long long>(verdict.steady_at);
  if (std::isfinite(verdict.measure)) g.attributes["measure"] = verdict.measure;
  g.attributes["tolerance_force"] = t.force;
  g.attributes["tolerance_stroke"] = t.stroke;
  g.attributes["tolerance_pressure"] = t.pressure;
  g.attributes["pressure_floor"] = t.pressure_floor;
  g.attributes["consecutive"] = static_cast<long long>(t.consecutive);
  g.attributes["max_cycles"] = static_cast<long long>(t.max_cycles);
  g.attributes["time_limit"] = t.time_limit;
  g.attributes["pressure_drift"] = t.pressure_drift;
  g.attributes["drift_window"] = t.drift_window;
  for (const CycleSummary& c : cycles) {
    daq::MetadataGroup s{fmt::format("{:06}", c.cycle), {}, {}};
    s.attributes["start_ns"] = static_cast<long long>(c.start_ns);
    s.attributes["end_ns"] = static_cast<long long>(c.end_ns);
    s.attributes["stroke_min"] = c.stroke_min;
    s.attributes["stroke_max"] = c.stroke_max;
    s.attributes["force_min"] = c.force_min;
    s.attributes["force_max"] = c.force_max;
    // No pressure channel: the attribute is left out (NaN is no value for a reader to trust).
    if (!std::isnan(c.pressure_mean)) s.attributes["pressure_mean"] = c.pressure_mean;
    g.groups.push_back(std::move(s));
  }
  return g;
}

std::vector<CycleSummary> CyclesFromGroup(const daq::MetadataGroup& g) {
  std::vector<CycleSummary> cycles;
  for (const daq::MetadataGroup& s : g.groups) {
    const auto get = [&](const char* key) {
      const auto v = s.number(key);
      if (!v) throw daq::SessionError(fmt::format("group '{}/{}': attribute '{}' missing or not a number", g.name, s.name, key));
      return *v;
    };
    CycleSummary c;
    try {
      c.cycle = std::stol(s.name);
    } catch (const std::invalid_argument&) {
      throw daq::SessionError(fmt::format("group '{}/{}': the name is no cycle number", g.name, s.name));
    } catch (const std::out_of_range&) {
      throw daq::SessionError(fmt::format("group '{}/{}': the name is no cycle number", g.name, s.name));
    }
    c.start_ns = static_cast<std::int64_t>(get("start_ns"));
    c.end_ns = static_cast<std::int64_t>(get("end_ns"));
    c.stroke_min = get("stroke_min");
    c.stroke_max = get("stroke_max");
    c.force_min = get("force_min");
    c.force_max = get("force_max");
    c.pressure_mean = s.number("pressure_mean").value_or(std::numeric_limits<double>::quiet_NaN());
    cycles.push_back(c);
  }
  return cycles;
}

SteadyStateTolerances TolerancesFromGroup(const daq::MetadataGroup& g) {
  const auto get = [&](const char* key) {
    const auto v = g.number(key);
    if (!v) throw daq::SessionError(fmt::format("group '{}': attribute '{}' missing or not a number", g.name, key));
    return *v;
  };
  SteadyStateTolerances t;
  t.force = get("tolerance_force");
  t.stroke = get("tolerance_stroke");
  t.pressure = get("tolerance_pressure");
  t.pressure_floor = get("pressure_floor");
  t.consecutive = static_cast<int>(get("consecutive"));
  t.max_cycles = static_cast<int>(get("max_cycles"));
  t.time_limit = get("time_limit");
  // Not stored before the drift test existed: such runs were judged without it.
  t.pressure_drift = g.number("pressure_drift").value_or(0.999);
  t.drift_window = g.number("drift_window").value_or(0.0);
  return t;
}

}  // namespace strut::rig
