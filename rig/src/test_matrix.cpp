#include "strut/rig/test_matrix.h"

namespace strut::rig {

daq::Experiment PeriodicExperimentOf(const MatrixEntry& entry, long periods, double sample_rate) {
  return {.label = entry.label,
          .kind = daq::ExperimentKind::kPeriodic,
          .sample_rate = sample_rate,
          .frequency = entry.frequency,
          .amplitude = entry.amplitude,
          .static_position = entry.static_position,
          .periods = periods,
          .group = entry.group};
}

std::vector<MatrixEntry> StandardMatrix() {
  // Static position / amplitude in mm, as read from the paper's Table 1 (method.md).
  struct Row {
    const char* label;
    const char* group;
    double frequency, static_mm, amplitude_mm;
  };
  static constexpr Row rows[] = {
      {"a", "middle", 0.04, 133, 127}, {"b", "middle", 0.1, 133, 127}, {"c", "high", 0.2, 179, 75},
      {"d", "high", 0.5, 219, 32},     {"e", "high", 1.0, 229, 20},    {"f", "high", 2.0, 249, 10},
      {"g", "middle", 0.2, 133, 78},   {"h", "middle", 0.5, 133, 34},  {"i", "middle", 1.0, 133, 21},
      {"j", "middle", 2.0, 133, 10},   {"k", "low", 0.2, 80, 79},      {"l", "low", 0.5, 39, 35},
      {"m", "low", 1.0, 22, 17},       {"n", "low", 2.0, 14, 10},
  };
  std::vector<MatrixEntry> matrix;
  for (const Row& r : rows) matrix.push_back({r.label, r.group, r.frequency, r.static_mm * 1e-3, r.amplitude_mm * 1e-3});
  return matrix;
}

}  // namespace strut::rig
