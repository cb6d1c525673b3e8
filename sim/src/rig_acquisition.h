// The rig's acquisition: the three sensor channels with the faults that apply to an experiment,
// shared by SimulatedRig (per experiment) and SimulatedController (one continuous stream).
#pragma once

#include <random>
#include <string>
#include <vector>

#include "strut/daq/session.h"
#include "strut/sim/simulated_rig.h"
#include "strut/sim/truth.h"

namespace strut::sim {

//! The three sensor channels of one experiment, with the faults that apply to it.
struct Acquisition {
  SensorChannel stroke, force, pressure;
  std::vector<FaultSpec> stroke_faults, force_faults, pressure_faults;
  double pressure_reference;

  Acquisition(const Truth& truth, const std::string& label)
      : stroke(truth.sensors.stroke), force(truth.sensors.force), pressure(truth.sensors.pressure),
        pressure_reference(truth.acquisition.gauge_pressure ? daq::kGaugeReferencePa : 0.0) {
    for (const FaultSpec& f : truth.faults) {
      if (f.Applies(label, "stroke")) stroke_faults.push_back(f);
      if (f.Applies(label, "force")) force_faults.push_back(f);
      if (f.Applies(label, "pressure")) pressure_faults.push_back(f);
    }
  }
  //! Readings of a block: stroke as an ideal LVDT reads it (q + theta12), force, absolute pressure.
  SampleBlock Acquire(const std::string& label, const std::vector<double>& stroke_values,
                      const std::vector<double>& force_values, const std::vector<double>& pressure_values,
                      double rate, double start_time, bool recording, std::mt19937_64& rng) {
    SampleBlock b;
    b.experiment = label;
    b.start_time = start_time;
    b.sample_rate = rate;
    b.recording = recording;
    b.stroke = stroke.Acquire(stroke_values, rate, start_time, stroke_faults, rng);
    b.force = force.Acquire(force_values, rate, start_time, force_faults, rng);
    std::vector<double> p(pressure_values);
    for (double& v : p) v -= pressure_reference;
    b.pressure = pressure.Acquire(p, rate, start_time, pressure_faults, rng);
    return b;
  }
  daq::Channel PressureChannel(std::vector<double> samples, bool gauge) const {
    return daq::Channel{"pressure", "Pa", gauge ? "gauge" : "absolute", std::move(samples)};
  }
};

//! The loop controls the LVDT's noise-free reading y; the damper's measured stroke q + theta12 is
//! that reading with the LVDT's calibration error undone: u = (y - offset) / (1 + gain_error).
struct LvdtInverse {
  explicit LvdtInverse(const SensorOptions& lvdt) : scale(1.0 / (1.0 + lvdt.gain_error)), offset(lvdt.offset) {}
  InputSample operator()(const InputSample& y) const {
    return {(y.value - offset) * scale, y.rate * scale, y.accel * scale};
  }
  double scale, offset;
};

}  // namespace strut::sim
