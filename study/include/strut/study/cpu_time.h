// The clocks the studies time with: they run on shared machines, where CPU time says more than wall
// time (another process's load does not count), and the machine's load average to print beside.
#pragma once

#include <pthread.h>

#include <array>

namespace strut::study {

//! CPU seconds used by this thread so far (CLOCK_THREAD_CPUTIME_ID).
double ThreadSeconds();

//! CPU seconds used so far by another thread of this process, while it runs (pthread_getcpuclockid;
//! NaN once it has ended): to take a helper's share out of ProcessSeconds.
double ThreadSeconds(pthread_t thread);

//! CPU seconds used by the whole process so far, every thread (CLOCK_PROCESS_CPUTIME_ID): for
//! work that runs on helper threads too (the recorder's writer, the estimator's threads).
double ProcessSeconds();

//! The load averages over 1, 5 and 15 minutes (getloadavg); NaN where the system gives none.
std::array<double, 3> LoadAverages();

}  // namespace strut::study
