#include "strut/study/discover_timing.h"

#include <chrono>

#include "strut/ident/discover.h"
#include "strut/sim/simulated_rig.h"
#include "strut/sim/truth.h"
#include "strut/study/cpu_time.h"
#include "strut/study/statistics.h"

namespace strut::study {

DiscoverTimingStudy RunDiscoverTiming(int repeats) {
  const sim::SimulatedRig rig(sim::DefaultTruth());
  const daq::Session session = rig.RunMatrix(rig::StandardMatrixPlan());
  ident::SessionFitOptions fit;
  fit.composition = "1dof";
  const ident::FitData data =
      ident::PrepareFitData(session, "simulated session", ident::Model::Build("1dof", fit.causality), fit.estimator.n);
  DiscoverTimingStudy study;
  study.settings.resize(2);  // 1 and 2 threads
  study.settings[1].threads = 2;
  study.load_before = LoadAverages()[0];
  for (int r = 0; r < repeats; ++r)
    for (DiscoverTiming& s : study.settings) {
      ident::DiscoverOptions options;
      options.threads = s.threads;
      const double cpu_start = ProcessSeconds();
      const auto start = std::chrono::steady_clock::now();
      s.missing = ident::Discover(data, fit, options).missing;
      s.wall.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
      s.cpu.push_back(ProcessSeconds() - cpu_start);
    }
  study.load_after = LoadAverages()[0];
  for (DiscoverTiming& s : study.settings) {
    s.median_wall = Median(s.wall);
    s.median_cpu = Median(s.cpu);
  }
  return study;
}

}  // namespace strut::study
