// The cross-check of the Silverbox test simulation: SUNDIALS IDA (sim::TransientSimulator) on the
// chosen model and the same band-limited input as the RK4 run.
#include <algorithm>
#include <chrono>
#include <cmath>

#include "strut/sim/transient.h"
#include "strut/study/oscillator.h"
#include "strut/study/silverbox.h"

namespace strut::study {

SilverboxSimulationCheck CheckArrowSimulation(const daq::Session& session, const SilverboxResult& result) {
  const SilverboxCandidate& best = result.best();
  const ident::Model model = ident::Model::Build(best.model, ident::Causality::kForceInput);
  const daq::Experiment& arrow = session.experiment("arrow");
  const std::vector<double>& u = arrow.channel("u").samples;
  constexpr int kFine = 16;
  const double fs = arrow.sample_rate, h = 1.0 / (fs * kFine);
  // The same band-limited input as the RK4 run, evaluated between its fine points by cubic Lagrange.
  const std::vector<double> fine = BandLimitedRecord(u, kFine);
  const sim::InputSignal input([&fine, h](double t) {
    const double p = t / h;
    const long i = static_cast<long>(std::floor(p));
    const double s = p - i;
    const auto at = [&](long j) { return fine[std::clamp<long>(j, 0, static_cast<long>(fine.size()) - 1)]; };
    const double v = -s * (s - 1) * (s - 2) / 6 * at(i - 1) + (s + 1) * (s - 1) * (s - 2) / 2 * at(i) -
                     (s + 1) * s * (s - 2) / 2 * at(i + 1) + (s + 1) * s * (s - 1) / 6 * at(i + 2);
    return sim::InputSample{v, 0.0, 0.0};
  });
  sim::TransientOptions to;
  to.rtol = 1e-8;
  to.atol_factor = 10.0;
  to.max_steps = 20'000'000;
  const sim::TransientSimulator simulator(model, to);
  std::vector<double> times(u.size());
  for (std::size_t i = 0; i < times.size(); ++i) times[i] = i / fs;
  const auto t0 = std::chrono::steady_clock::now();
  const sim::TransientResult ida = simulator.Simulate(best.fit.parameters.values(), input, times);
  SilverboxSimulationCheck check;
  check.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  check.steps = ida.steps;
  const Eigen::VectorXd y = ida.channel("y");
  double max_diff = 0.0, sum = 0.0;
  long count = 0;
  for (std::size_t i = 0; i < times.size(); ++i) max_diff = std::max(max_diff, std::abs(y[i] - result.arrow_simulated[i]));
  for (long i = SilverboxLayout::kTransient; i < static_cast<long>(times.size()); ++i, ++count)
    sum += std::pow(result.arrow_measured[i] - y[i], 2);
  check.max_difference_uv = 1e6 * max_diff;
  check.test_arrow_rms_mv = 1e3 * std::sqrt(sum / count);
  return check;
}

}  // namespace strut::study
