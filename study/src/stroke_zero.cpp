#include "strut/study/stroke_zero.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>

#include "strut/daq/recorder.h"
#include "strut/daq/rig_devices.h"
#include "strut/rig/campaign.h"
#include "strut/sim/rig_server.h"
#include "strut/study/statistics.h"

namespace strut::study {

rig::RunReport RunTopOutReference(const sim::Truth& truth, const rig::TopOutOptions& options, double speed,
                                  const std::string& path) {
  const sim::SimulatedRigFactory factory(truth, speed);
  const daq::RigDeviceFactory* factories[] = {&factory};
  daq::RigConnection connection;
  connection.controller = "sim";
  const daq::RigDevices devices = daq::ConnectRig(connection, factories);
  const rig::RunStart start{path, false, true, truth.damper_serial};
  const rig::SafetyConfig safety;
  daq::Recorder recorder =
      rig::OpenRunRecorder(start, rig::RunMetadata(truth.damper_serial, devices.description, "", "none", safety), 0);
  rig::RunnerOptions runner_options;
  runner_options.stream_speed = speed;
  runner_options.top_out = options;
  rig::MatrixRunner runner(*devices.controller, *devices.acquisition, recorder, safety, runner_options);
  const rig::RunReport report = runner.Run({});
  recorder.Close();
  return report;
}

StrokeZeroUnit ReferenceDrawnUnit(const StrokeZeroOptions& options, int u) {
  StrokeZeroUnit unit;
  unit.seed = options.draw.first_seed + static_cast<unsigned long>(u);
  const sim::Truth truth = DrawnUnitTruth(options.draw, unit.seed);
  const ident::Model model = truth.BuildModel(ident::Causality::kStrokeInput);
  const ident::ParameterSet p = truth.Parameters(model);
  unit.theta12 = p.value(p.position_of_index(12));
  unit.truth = truth.TopOutReading();
  const auto start = std::chrono::steady_clock::now();
  const rig::RunReport report = RunTopOutReference(truth, options.top_out, options.speed, options.scratch);
  unit.wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::filesystem::remove(options.scratch);
  if (report.top_out) {
    unit.found = true;
    unit.zero = report.top_out->zero;
    unit.sd = report.top_out->sd;
    unit.fit_sd = report.top_out->fit_sd;
    unit.stiffness = report.top_out->stiffness;
  } else {
    unit.failure = report.top_out_failure.empty() ? report.cause : report.top_out_failure;
  }
  return unit;
}

StrokeZeroStudy SummariseStrokeZero(std::vector<StrokeZeroUnit> units) {
  StrokeZeroStudy s;
  s.units = std::move(units);
  std::vector<double> errors, errors12, sds, walls;
  for (const StrokeZeroUnit& u : s.units) {
    walls.push_back(u.wall);
    if (!u.found) continue;
    ++s.found;
    errors.push_back(u.error());
    errors12.push_back(u.zero - u.theta12);
    sds.push_back(u.sd);
    s.largest_error = std::max(s.largest_error, std::abs(u.error()));
    if (std::abs(u.error()) <= u.sd) ++s.within_1sd;
    if (std::abs(u.error()) <= 1.96 * u.sd) ++s.within_2sd;
  }
  const auto mean_sd = [](const std::vector<double>& v, double& mean, double& sd) {
    if (v.empty()) return;
    double sum = 0;
    for (double x : v) sum += x;
    mean = sum / static_cast<double>(v.size());
    double ss = 0;
    for (double x : v) ss += (x - mean) * (x - mean);
    sd = v.size() > 1 ? std::sqrt(ss / static_cast<double>(v.size() - 1)) : 0.0;
  };
  mean_sd(errors, s.mean_error, s.sd_error);
  mean_sd(errors12, s.mean_error_theta12, s.sd_error_theta12);
  if (!sds.empty()) s.median_sd = Median(sds);
  if (!walls.empty()) s.wall_median = Median(walls);
  return s;
}

std::string StrokeZeroLine(const StrokeZeroUnit& u) {
  if (!u.found) return fmt::format("unit {:>6}  theta12 {:+.4f} mm  NOT FOUND: {}", u.seed, u.theta12 * 1e3, u.failure);
  return fmt::format("unit {:>6}  theta12 {:+.4f} mm  reads {:+.4f} mm  found {:+.4f} mm  sd {:.4f} mm  error {:+.2f} um "
                     "({:+.2f} sd)  contact {:.3g} N/m  {:.1f} s",
                     u.seed, u.theta12 * 1e3, u.truth * 1e3, u.zero * 1e3, u.sd * 1e3, u.error() * 1e6,
                     u.error() / u.sd, u.stiffness, u.wall);
}

std::string StrokeZeroSummary(const StrokeZeroOptions& o, const StrokeZeroStudy& s) {
  const double n = static_cast<double>(std::max<long>(1, s.found));
  std::string text = fmt::format(
      "top-out reference on {} drawn units (seeds {}..{}, {}{}{}), search {:.1f} .. {:.1f} mm at {:.3g} mm/s, force "
      "limit {:.0f} N, served at {}x\n",
      s.units.size(), o.draw.first_seed, o.draw.first_seed + s.units.size() - 1, o.draw.base,
      o.draw.servo ? ", servo actuator" : ", ideal actuator",
      o.draw.shipped_calibration ? ", shipped transducers" : ", calibrated transducers", o.top_out.from * 1e3,
      o.top_out.to * 1e3, o.top_out.rate * 1e3, o.top_out.force_drop, o.speed);
  text += fmt::format("  found: {}/{}\n", s.found, s.units.size());
  text += fmt::format("  error against the LVDT's reading at full extension: mean {:+.2f} um, sd {:.2f} um, largest "
                      "{:.2f} um\n",
                      s.mean_error * 1e6, s.sd_error * 1e6, s.largest_error * 1e6);
  text += fmt::format("  error against theta12 itself: mean {:+.2f} um, sd {:.2f} um\n", s.mean_error_theta12 * 1e6,
                      s.sd_error_theta12 * 1e6);
  text += fmt::format("  recorded sd: median {:.2f} um (the 2 mm prior it replaces is {:.0f} times wider)\n",
                      s.median_sd * 1e6, s.median_sd > 0 ? 2e-3 / s.median_sd : 0.0);
  text += fmt::format("  coverage: within 1 sd {}/{} ({:.2f}), within 1.96 sd {}/{} ({:.2f})\n", s.within_1sd, s.found,
                      s.within_1sd / n, s.within_2sd, s.found, s.within_2sd / n);
  text += fmt::format("  wall per unit: median {:.1f} s\n", s.wall_median);
  return text;
}

}  // namespace strut::study
