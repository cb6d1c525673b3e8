// The set-point the controller and register tests write (on strut_daq): experiment h of the standard matrix.
#pragma once

#include "strut/daq/controller.h"

namespace strut::test {

//! Experiment h of the standard matrix (middle position, 0.5 Hz, 34 mm) in stroke control, inside
//! the rig's stroke and force limits, ramped in and out over `ramp_cycles`.
inline daq::SetPoint ExperimentHSetPoint(int ramp_cycles) {
  daq::SetPoint s;
  s.mode = daq::ControlMode::kStroke;
  s.static_position = 0.133;
  s.amplitude = 0.034;
  s.frequency = 0.5;
  s.ramp_cycles = ramp_cycles;
  s.static_rate = 0.02;
  s.limits = {0.005, 0.35, -4.0e4, 4.5e4};
  return s;
}

}  // namespace strut::test
