// CPU time of the calling thread, for benchmarks that time one thread's work on a shared machine.
#pragma once

#include <time.h>

namespace strut::tools {

//! CPU seconds used by this thread so far (CLOCK_THREAD_CPUTIME_ID).
inline double ThreadSeconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

}  // namespace strut::tools
