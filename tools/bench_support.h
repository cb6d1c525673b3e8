// What the benchmarks share: CPU time of one thread and of the whole process (they run on a shared
// machine) and the Wilson interval of the fractions they report.
#pragma once

#include <time.h>

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

namespace strut::tools {

//! CPU seconds used by this thread so far (CLOCK_THREAD_CPUTIME_ID).
inline double ThreadSeconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

//! CPU seconds used by the whole process so far, every thread (CLOCK_PROCESS_CPUTIME_ID): for
//! work that runs on helper threads too (the recorder's writer).
inline double ProcessSeconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

//! Wilson score interval (95 %) of a binomial fraction k / total; NaN for no trials.
inline std::pair<double, double> Wilson(long k, long total) {
  if (total <= 0) return {NAN, NAN};
  const double z = 1.959963984540054, p = static_cast<double>(k) / total, nn = static_cast<double>(total);
  const double centre = (p + z * z / (2 * nn)) / (1 + z * z / nn);
  const double half = z / (1 + z * z / nn) * std::sqrt(p * (1 - p) / nn + z * z / (4 * nn * nn));
  return {centre - half, centre + half};
}

//! The median (the mean of the middle two for an even count); NaN for none.
inline double Median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

}  // namespace strut::tools
