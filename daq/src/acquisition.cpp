// Value types of the acquisition interface: calibration, time pairs, quality names.
#include "strut/daq/acquisition.h"

#include <fmt/format.h>
#include <time.h>

#include <cmath>

namespace strut::daq {

Calibration Calibration::FromRange16(double min, double max) {
  Calibration c;
  // A span beyond the largest double (values near +-1.8e308) is scaled first.
  c.gain = std::isfinite(max - min) ? (max - min) / 65535.0 : max / 65535.0 - min / 65535.0;
  c.offset = min + 32768.0 * c.gain;
  c.range_min = min;
  c.range_max = max;
  return c;
}

std::int16_t Calibration::ToCounts16(double si) const {
  const double counts = std::round((si - offset) / gain);
  if (!(counts > -32768.0)) return -32768;  // also NaN: the low rail, which reads as over-range
  if (counts > 32767.0) return 32767;
  return static_cast<std::int16_t>(counts);
}

bool Calibration::IsValid(std::string* error) const {
  std::string why;
  if (!std::isfinite(gain) || gain == 0.0)
    why = fmt::format("gain {} is not a finite, non-zero number", gain);
  else if (!std::isfinite(offset))
    why = fmt::format("offset {} is not finite", offset);
  else if (std::isnan(range_min) || std::isnan(range_max) || !(range_min < range_max))
    why = fmt::format("range [{}, {}] is empty", range_min, range_max);
  if (why.empty()) return true;
  if (error) *error = why;
  return false;
}

namespace {
std::int64_t Ns(clockid_t clock) {
  timespec t{};
  clock_gettime(clock, &t);
  return static_cast<std::int64_t>(t.tv_sec) * 1'000'000'000 + t.tv_nsec;
}
}  // namespace

std::int64_t MonotonicNs() { return Ns(CLOCK_MONOTONIC); }

TimePair NowTimePair() {
  TimePair best;
  std::int64_t best_bracket = INT64_MAX;
  for (int i = 0; i < 3; ++i) {
    const std::int64_t before = Ns(CLOCK_MONOTONIC);
    const std::int64_t utc = Ns(CLOCK_REALTIME);
    const std::int64_t after = Ns(CLOCK_MONOTONIC);
    if (after - before < best_bracket) {
      best_bracket = after - before;
      best = {before + (after - before) / 2, utc};
    }
  }
  return best;
}

std::string Quality::ToString() const {
  static constexpr std::pair<Flag, const char*> kNames[] = {
      {kSequenceGap, "sequence-gap"}, {kOverRange, "over-range"}, {kErrorPassive, "error-passive"},
      {kBusOff, "bus-off"},           {kDeviceFault, "device-fault"}, {kStale, "stale"},
      {kCorruptFrames, "corrupt-frames"}, {kBusErrors, "bus-errors"}};
  std::string s;
  for (const auto& [flag, name] : kNames)
    if (has(flag)) {
      if (!s.empty()) s += '|';
      s += name;
    }
  return s.empty() ? "good" : s;
}

std::string_view ToString(AcquisitionEvent::Kind kind) {
  switch (kind) {
    case AcquisitionEvent::Kind::kSequenceGap: return "sequence-gap";
    case AcquisitionEvent::Kind::kCorruptFrames: return "corrupt-frames";
    case AcquisitionEvent::Kind::kBusErrors: return "bus-errors";
    case AcquisitionEvent::Kind::kErrorPassive: return "error-passive";
    case AcquisitionEvent::Kind::kBusOff: return "bus-off";
    case AcquisitionEvent::Kind::kBusRecovered: return "bus-recovered";
    case AcquisitionEvent::Kind::kDeviceStatus: return "device-status";
    case AcquisitionEvent::Kind::kStale: return "stale";
    case AcquisitionEvent::Kind::kResumed: return "resumed";
    case AcquisitionEvent::Kind::kReceiverDrops: return "receiver-drops";
    case AcquisitionEvent::Kind::kResynchronised: return "resynchronised";
  }
  return "unknown";
}

}  // namespace strut::daq
