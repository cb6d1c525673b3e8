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
  std::string s;
  std::size_t start = 0;
  while (start <= comment.size() && !comment.empty()) {
    const auto end = comment.find('\n', start);
    s += "# " + comment.substr(start, end == std::string::npos ? std::string::npos : end - start) + "\n";
    if (end == std::string::npos) break;
    start = end + 1;
  }
  s += fmt::format("sample_rate = {}\n", kQcSampleRate);
  s += fmt::format("periods = {}\n", kQcPeriods);
  for (const auto& e : QcExperiments())
    s += fmt::format("\n[[experiment]]\nlabel = \"{}\"\ngroup = \"{}\"\nfrequency = {}\nstatic_position = {}\n"
                     "amplitude = {}\n",
                     e.label, e.group, e.frequency, e.static_position, e.amplitude);
  return s;
}

}  // namespace strut::qc
