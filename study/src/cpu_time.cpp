#include "strut/study/cpu_time.h"

#include <stdlib.h>
#include <time.h>

#include <cmath>

namespace strut::study {

double ThreadSeconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

double ThreadSeconds(pthread_t thread) {
  clockid_t clock{};
  timespec t{};
  if (pthread_getcpuclockid(thread, &clock) != 0 || clock_gettime(clock, &t) != 0) return NAN;
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

double ProcessSeconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

std::array<double, 3> LoadAverages() {
  double load[3];
  const int n = getloadavg(load, 3);
  std::array<double, 3> out{NAN, NAN, NAN};
  for (int i = 0; i < n && i < 3; ++i) out[i] = load[i];
  return out;
}

}  // namespace strut::study
