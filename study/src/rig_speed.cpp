#include "strut/study/rig_speed.h"

#include <algorithm>
#include <chrono>
#include <filesystem>

#include "strut/study/cpu_time.h"
#include "strut/study/statistics.h"

namespace strut::study {

double RecordedSeconds(const daq::Session& s) {
  double seconds = 0.0;
  for (const daq::Experiment& e : s.experiments) seconds += static_cast<double>(e.sample_count()) / e.sample_rate;
  return seconds;
}

SimMatrixTiming TimeSimMatrix(const sim::Truth& truth, const rig::MatrixPlan& plan, unsigned long seed, int repeats,
                              const std::string& path) {
  SimMatrixTiming t;
  std::vector<double> walls, cpus;
  for (int k = 0; k < repeats; ++k) {
    const double cpu0 = ProcessSeconds();
    const auto t0 = std::chrono::steady_clock::now();
    const sim::SimulatedRig simulated(truth);
    sim::RigRunOptions run;
    run.seed = seed;
    std::vector<sim::PeriodicRunReport> reports;
    const daq::Session session = simulated.RunMatrix(plan, run, &reports);
    daq::WriteSession(path, session);
    walls.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    cpus.push_back(ProcessSeconds() - cpu0);
    t.simulated = 0.0;
    for (const sim::PeriodicRunReport& r : reports) t.simulated += r.simulated_seconds;
    t.recorded = RecordedSeconds(session);
    std::filesystem::remove(path);
  }
  t.wall = Median(walls);
  t.cpu = Median(cpus);
  return t;
}

RigSpeedRow SummariseSpeed(double speed, std::vector<RigRunFigures> runs, std::size_t experiments) {
  RigSpeedRow row;
  row.speed = speed;
  row.runs = std::move(runs);
  const auto median = [&](auto field) {
    std::vector<double> v;
    for (const RigRunFigures& f : row.runs) v.push_back(field(f));
    return Median(v);
  };
  row.wall = median([](const RigRunFigures& f) { return f.wall; });
  row.cpu = median([](const RigRunFigures& f) { return f.cpu; });
  row.plant = median([](const RigRunFigures& f) { return f.plant_cpu; });
  row.simulated = median([](const RigRunFigures& f) { return f.simulated; });
  row.recorded = median([](const RigRunFigures& f) { return f.recorded; });
  row.behind = median([](const RigRunFigures& f) { return f.max_lateness; });
  row.per_wall = median([](const RigRunFigures& f) { return f.simulated / f.wall; });
  row.per_cpu = median([](const RigRunFigures& f) { return f.simulated / f.cpu; });
  row.complete = experiments;
  for (const RigRunFigures& f : row.runs) {
    row.complete = std::min(row.complete, f.complete);
    row.lost = std::max(row.lost, f.lost_sets);
    row.gaps = std::max(row.gaps, f.gaps);
    row.refused = std::max(row.refused, f.refused_frames);
    row.kept += f.kept_up(experiments) ? 1 : 0;
  }
  return row;
}

std::optional<double> FastestKeptUp(const std::vector<RigSpeedRow>& rows) {
  std::optional<double> fastest;
  for (const RigSpeedRow& row : rows)
    if (row.kept_up() && (!fastest || row.speed > *fastest)) fastest = row.speed;
  return fastest;
}

}  // namespace strut::study
