#include "strut/ident/transient_fit.h"

#include <Eigen/Dense>
#include <cmath>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

namespace strut::ident {
namespace {

//! Noise variance of the last second (at least 20 samples): the spread about a quadratic trend
//! (the stroke creeps and the pressure falls as the gas cools), with 3 degrees of freedom taken.
double RestNoiseVariance(const std::vector<double>& time, const Eigen::VectorXd& samples) {
  const Eigen::Index n = samples.size();
  Eigen::Index first = n;
  while (first > 0 && time[first - 1] >= time.back() - 1.0) --first;
  const Eigen::Index count = n - first;
  // A record shorter than 2 s has no second at rest.
  if (count < 20 || time.back() < 2.0) return NAN;
  Eigen::MatrixXd basis(count, 3);
  const double t0 = time[first], span = std::max(time.back() - t0, 1e-12);
  for (Eigen::Index i = 0; i < count; ++i) {
    const double s = (time[first + i] - t0) / span;
    basis(i, 0) = 1.0;
    basis(i, 1) = s;
    basis(i, 2) = s * s;
  }
  const Eigen::VectorXd y = samples.tail(count);
  const Eigen::VectorXd coefficients = basis.colPivHouseholderQr().solve(y);
  return (y - basis * coefficients).squaredNorm() / static_cast<double>(count - 3);
}

}  // namespace

const std::vector<std::string>& TransientFitChannels() {
  static const std::vector<std::string> channels = {"stroke", "pressure"};
  return channels;
}

std::string TransientChannelName(const std::string& kind, const std::string& channel) { return kind + ":" + channel; }

std::vector<TransientExperimentData> PrepareTransientExperiments(const daq::Session& session, const std::string& name) {
  std::vector<TransientExperimentData> out;
  for (const daq::Experiment& e : session.experiments) {
    if (e.kind != daq::ExperimentKind::kDrop) continue;
    if (e.status != "complete") {
      spdlog::info("{}: drop experiment '{}' skipped ({})", name, e.label, e.status);
      continue;
    }
    const auto fail = [&](const std::string& what) {
      return daq::SessionError(fmt::format("{}: drop experiment '{}': {}", name, e.label, what));
    };
    if (!(e.drop_mass > 0) || !std::isfinite(e.drop_mass))
      throw fail(fmt::format("drop_mass must be a positive mass in kg, got {}", e.drop_mass));
    if (!std::isfinite(e.impact_velocity) || e.impact_velocity < 0)
      throw fail(fmt::format("impact_velocity must be >= 0 m/s, got {}", e.impact_velocity));
    if (e.time.size() < 10) throw fail(fmt::format("{} samples; a fit needs at least 10", e.time.size()));
    if (e.time.front() != 0.0)
      throw fail(fmt::format("time starts at {} s; a drop record starts at contact, time 0", e.time.front()));
    for (std::size_t i = 1; i < e.time.size(); ++i)
      if (!(e.time[i] > e.time[i - 1]))
        throw fail(fmt::format("time does not increase at sample {} ({} s after {} s)", i, e.time[i], e.time[i - 1]));
    TransientExperimentData d;
    d.session = name;
    d.label = e.label;
    d.kind = "drop";
    d.drop_mass = e.drop_mass;
    d.impact_velocity = e.impact_velocity;
    d.time = e.time;
    for (const std::string& channel : TransientFitChannels()) {
      if (!e.find_channel(channel)) {
        if (channel == "stroke") throw fail("no 'stroke' channel; a drop is fitted on its stroke");
        spdlog::info("{}: drop experiment '{}' has no '{}' channel; fitted without it", name, e.label, channel);
        continue;
      }
      const std::vector<double> samples = channel == "pressure" ? e.absolute_pressure() : e.channel(channel).samples;
      if (samples.size() != e.time.size())
        throw fail(fmt::format("channel '{}' has {} samples, time {}", channel, samples.size(), e.time.size()));
      TransientChannel c;
      c.samples = Eigen::Map<const Eigen::VectorXd>(samples.data(), static_cast<Eigen::Index>(samples.size()));
      for (Eigen::Index i = 0; i < c.samples.size(); ++i)
        if (!std::isfinite(c.samples[i]))
          throw fail(fmt::format("channel '{}' sample {} (t = {} s) is not finite", channel, i, e.time[i]));
      c.noise_variance = RestNoiseVariance(d.time, c.samples);
      d.channels[channel] = std::move(c);
    }
    out.push_back(std::move(d));
  }
  return out;
}

}  // namespace strut::ident
