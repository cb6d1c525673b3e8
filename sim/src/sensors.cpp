#include "strut/sim/sensors.h"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <stdexcept>

namespace strut::sim {

bool SensorOptions::IsValid(std::string* error) const {
  const auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (!std::isfinite(range_min) || !std::isfinite(range_max) || !(range_max > range_min))
    return fail(fmt::format("range must be two finite values, low < high, got [{}, {}]", range_min, range_max));
  if (!std::isfinite(noise) || noise < 0) return fail(fmt::format("noise must be >= 0, got {}", noise));
  if (!std::isfinite(offset)) return fail("offset must be finite");
  if (!std::isfinite(gain_error) || std::abs(gain_error) >= 0.5)
    return fail(fmt::format("gain_error must be between -0.5 and 0.5, got {}", gain_error));
  if (bits != 0 && (bits < 8 || bits > 24)) return fail(fmt::format("bits must be 0 (ideal) or 8..24, got {}", bits));
  return true;
}

double SensorOptions::lsb() const {
  return bits == 0 ? 0.0 : (range_max - range_min) / (std::ldexp(1.0, bits) - 1.0);
}

bool SensorSet::IsValid(std::string* error) const {
  std::string e;
  if (!stroke.IsValid(&e)) {
    if (error) *error = "stroke sensor: " + e;
    return false;
  }
  if (!force.IsValid(&e)) {
    if (error) *error = "force sensor: " + e;
    return false;
  }
  if (!pressure.IsValid(&e)) {
    if (error) *error = "pressure sensor: " + e;
    return false;
  }
  return true;
}

std::string_view ToString(FaultKind kind) {
  switch (kind) {
    case FaultKind::kDropout: return "dropout";
    case FaultKind::kStuck: return "stuck";
    case FaultKind::kSpikes: return "spikes";
    case FaultKind::kDisconnected: return "disconnected";
  }
  return "?";
}

FaultKind ParseFaultKind(std::string_view text) {
  for (FaultKind k : {FaultKind::kDropout, FaultKind::kStuck, FaultKind::kSpikes, FaultKind::kDisconnected})
    if (ToString(k) == text) return k;
  throw std::invalid_argument(
      fmt::format("unknown fault kind '{}' (known: dropout, stuck, spikes, disconnected)", text));
}

bool FaultSpec::IsValid(std::string* error) const {
  const auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (channel != "stroke" && channel != "force" && channel != "pressure")
    return fail(fmt::format("channel must be stroke, force or pressure, got '{}'", channel));
  if (experiment.empty()) return fail("experiment must be a label or \"*\"");
  if (!std::isfinite(start) || start < 0) return fail(fmt::format("start must be >= 0 s, got {}", start));
  if (!std::isfinite(duration) || duration < 0) return fail(fmt::format("duration must be >= 0 s, got {}", duration));
  if (kind == FaultKind::kSpikes) {
    if (!std::isfinite(rate) || !(rate > 0)) return fail(fmt::format("spike rate must be positive, got {}", rate));
    if (!std::isfinite(amplitude) || !(amplitude > 0) || amplitude > 2)
      return fail(fmt::format("spike amplitude must be 0..2 (fraction of the range), got {}", amplitude));
  }
  return true;
}

bool FaultSpec::Applies(std::string_view label, std::string_view channel_name) const {
  return channel == channel_name && (experiment == "*" || experiment == label);
}

SensorChannel::SensorChannel(SensorOptions options) : options_(std::move(options)) {
  std::string error;
  if (!options_.IsValid(&error)) throw std::invalid_argument("sensor: " + error);
}

double SensorChannel::Quantise(double value) const {
  if (options_.bits == 0) return value;
  const double lsb = options_.lsb();
  const double top = std::ldexp(1.0, options_.bits) - 1.0;
  const double code = std::clamp(std::round((value - options_.range_min) / lsb), 0.0, top);
  return options_.range_min + code * lsb;
}

std::vector<double> SensorChannel::Acquire(std::span<const double> physical, double sample_rate, double start_time,
                                           std::span<const FaultSpec> faults, std::mt19937_64& rng) {
  std::normal_distribution<double> unit(0.0, 1.0);
  const std::size_t count = physical.size();
  std::vector<double> analog(count);
  for (std::size_t i = 0; i < count; ++i)
    analog[i] = (1.0 + options_.gain_error) * physical[i] + options_.offset + options_.noise * unit(rng);
  const auto time = [&](std::size_t i) { return start_time + static_cast<double>(i) / sample_rate; };
  for (const FaultSpec& f : faults) {
    const double end = f.duration > 0 ? f.start + f.duration : INFINITY;
    const auto active = [&](std::size_t i) { return time(i) >= f.start - 1e-12 && time(i) < end - 1e-12; };
    switch (f.kind) {
      case FaultKind::kDropout:
        for (std::size_t i = 0; i < count; ++i)
          if (active(i)) analog[i] = options_.offset + options_.noise * unit(rng);
        break;
      case FaultKind::kStuck: {
        auto held = std::find_if(stuck_.begin(), stuck_.end(), [&](const auto& s) { return s.first == f.start; });
        for (std::size_t i = 0; i < count; ++i) {
          if (!active(i)) continue;
          if (held == stuck_.end()) {
            stuck_.emplace_back(f.start, analog[i]);
            held = stuck_.end() - 1;
          }
          analog[i] = held->second;
        }
        break;
      }
      case FaultKind::kSpikes: {
        // Each sample is a spike with probability rate / sample_rate, of random sign.
        std::bernoulli_distribution spike(std::min(1.0, f.rate / sample_rate));
        std::bernoulli_distribution positive(0.5);
        const double size = f.amplitude * (options_.range_max - options_.range_min);
        for (std::size_t i = 0; i < count; ++i)
          if (active(i) && spike(rng)) analog[i] += positive(rng) ? size : -size;
        break;
      }
      case FaultKind::kDisconnected:
        for (std::size_t i = 0; i < count; ++i)
          if (active(i)) analog[i] = options_.range_min - 1.0 * (options_.range_max - options_.range_min);
        break;
    }
  }
  for (double& v : analog) v = Quantise(v);
  if (options_.bits == 0) {
    // No converter: a disconnected channel still reads the lower rail.
    for (const FaultSpec& f : faults)
      if (f.kind == FaultKind::kDisconnected) {
        const double end = f.duration > 0 ? f.start + f.duration : INFINITY;
        for (std::size_t i = 0; i < count; ++i)
          if (time(i) >= f.start - 1e-12 && time(i) < end - 1e-12) analog[i] = options_.range_min;
      }
  }
  return analog;
}

}  // namespace strut::sim
