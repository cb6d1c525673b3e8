// The time of a full discovery run (`strut bench discover`): the 14-experiment standard matrix from
// the simulated rig with every effect on (the hardest case: every round refits all candidates),
// with one and with two estimator threads.
#pragma once

#include <string>
#include <vector>

namespace strut::study {

struct DiscoverTiming {
  int threads = 1;
  std::vector<double> wall, cpu;  //!< s per run; cpu: the whole process
  double median_wall = 0.0, median_cpu = 0.0;
  std::vector<std::string> missing;  //!< the terms the last run found
};

struct DiscoverTimingStudy {
  std::vector<DiscoverTiming> settings;  //!< 1 and 2 threads
  double load_before = 0.0, load_after = 0.0;  //!< 1 min load average around the runs
};

//! `repeats` runs per thread count; the counts alternate within each repeat, so a change in the
//! machine's load falls on both.
DiscoverTimingStudy RunDiscoverTiming(int repeats);

}  // namespace strut::study
