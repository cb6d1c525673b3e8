#include "strut/qc/matrix.h"

#include <fmt/format.h>

namespace strut::qc {

std::vector<rig::MatrixEntry> QcExperiments() {
  // label, group, frequency (Hz), static (m), amplitude (m): docs/qc.md says why each is there.
  return {
      {"q1", "middle", 0.1, 0.100, 0.080},  // gas law 20-180 mm, heat exchange, friction at slow reversals
      {"q2", "middle", 0.5, 0.100, 0.030},  // gas stiffness mid-stroke, nearly adiabatic
      {"q3", "middle", 2.0, 0.100, 0.010},  // inertia (moving mass) against the load-cell zero
      {"q4", "low", 1.0, 0.050, 0.040},     // 0.25 m/s: orifice (v^2) apart from seal damping (v)
  };
}

std::string QcMatrixFileText(const std::string& comment) {
  rig::MatrixPlan plan;
  plan.experiments = QcExperiments();
  plan.sample_rate = kQcSampleRate;
  plan.periods = kQcPeriods;
  return rig::MatrixFileText(plan, comment);
}

}  // namespace strut::qc
