#include "strut/sim/periodic_session.h"

#include <cmath>
#include <fmt/format.h>
#include <random>

#include "strut/ident/periodic.h"

namespace strut::sim {

daq::Session SimulatePeriodicSession(const std::string& composition, std::span<const double> theta,
                                     const std::vector<rig::MatrixEntry>& matrix, const PeriodicSessionOptions& options) {
  const ident::Model model = ident::Model::Build(composition, ident::Causality::kStrokeInput);
  ident::PeriodicSolverOptions solver_options;
  // Not the scheme a stroke-input fit uses (central4): no inverse crime. At 4000 points a period
  // backward2 is within about 1e-7 of the periodic solution.
  solver_options.scheme = ident::Scheme::kBackward2;
  ident::PeriodicSolver solver(model, solver_options);
  std::mt19937_64 rng(options.seed);
  std::normal_distribution<double> unit(0.0, 1.0);

  daq::Session session;
  session.created_utc = daq::UtcNowIso8601();
  session.damper_serial = options.damper_serial;
  session.rig = options.rig;
  for (std::size_t index = 0; index < matrix.size(); ++index) {
    const rig::MatrixEntry& entry = matrix[index];
    const std::optional<long> whole = daq::WholeSamplesPerPeriod(options.sample_rate, entry.frequency, 16);
    if (!whole)
      throw std::invalid_argument(fmt::format("experiment '{}': {} Hz at {} Hz sampling is not a whole number of samples "
                                              "per period",
                                              entry.label, entry.frequency, options.sample_rate));
    const long n = *whole;
    // Solve on a grid fine enough for the friction transitions (at least 4000 points a period),
    // then take every k-th point: the samples of the continuous signal, as an ADC sees it.
    // The stroke set-point is the sensor reading; the model's true stroke is reading - theta12.
    const long k = std::max<long>(1, (4000 + n - 1) / n);
    const ident::PeriodicSolution fine = solver.Solve(
        ident::PeriodicInput::Sine(entry.frequency, entry.static_position, entry.amplitude, static_cast<int>(n * k)),
        model.AtExperiment(std::vector<double>(theta.begin(), theta.end()),
                           {daq::OrderSessionTime(index, matrix.size()), entry.static_position}));
    struct Sampled {
      const ident::PeriodicSolution& s;
      long k;
      Eigen::VectorXd channel(const char* name) const {
        const Eigen::VectorXd all = s.channel(name);
        Eigen::VectorXd out(all.size() / k);
        for (Eigen::Index i = 0; i < out.size(); ++i) out[i] = all[i * k];
        return out;
      }
    } s{fine, k};
    const long start = std::uniform_int_distribution<long>(0, n - 1)(rng);  // arbitrary phase
    const long count = n * options.periods;

    daq::Experiment e = rig::PeriodicExperimentOf(entry, options.periods, options.sample_rate);
    e.time.resize(count);
    for (long i = 0; i < count; ++i) e.time[i] = i / options.sample_rate;
    const auto channel = [&](const char* name, const char* units, const Eigen::VectorXd& clean, double noise,
                             double offset) {
      daq::Channel c{name, units, "", std::vector<double>(count)};
      for (long i = 0; i < count; ++i) c.samples[i] = clean[(start + i) % n] + offset + noise * unit(rng);
      return c;
    };
    e.channels.push_back(channel("stroke", "m", s.channel("stroke"), options.noise.stroke, 0.0));
    e.channels.push_back(channel("force", "N", s.channel("force"), options.noise.force, 0.0));
    daq::Channel pressure = channel("pressure", "Pa", s.channel("pressure"), options.noise.pressure,
                                    options.gauge_pressure ? -daq::kGaugeReferencePa : 0.0);
    pressure.reference = options.gauge_pressure ? "gauge" : "absolute";
    e.channels.push_back(std::move(pressure));
    session.experiments.push_back(std::move(e));
  }
  return session;
}

void AddSensorNoise(daq::Session& session, const SensorNoise& noise, std::mt19937_64& rng) {
  std::normal_distribution<double> unit(0.0, 1.0);
  for (auto& e : session.experiments)
    for (auto& c : e.channels) {
      const double sd = c.name == "stroke" ? noise.stroke : c.name == "force" ? noise.force
                        : c.name == "pressure"                                ? noise.pressure
                                                                              : 0.0;
      if (sd > 0)
        for (double& v : c.samples) v += sd * unit(rng);
    }
}

}  // namespace strut::sim
