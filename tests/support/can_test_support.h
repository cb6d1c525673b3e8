// Helpers shared by the CAN tests: a four-channel module's options and hand-built frames.
#pragma once

#include <linux/can/error.h>

#include <cstdint>
#include <vector>

#include "strut/daq/can_acquisition.h"

namespace strut::test {

//! Stroke 10 µm per count, force 2 N per count from -1000 N, pressure from the 16-bit span of
//! [0, 20 MPa], temperature 0.01 K per count from 273.15 K: four different calibrations.
inline daq::CanAcquisitionOptions FourChannelOptions(bool fd = false, double sample_rate = 2000.0) {
  daq::CanAcquisitionOptions o;
  o.layout.fd = fd;
  o.layout.module = 5;
  o.sample_rate = sample_rate;
  daq::Calibration stroke;
  stroke.gain = 1e-5;
  stroke.range_min = -0.2;
  stroke.range_max = 0.2;
  daq::Calibration force;
  force.gain = 2.0;
  force.offset = -1000.0;
  daq::Calibration temperature;
  temperature.gain = 0.01;
  temperature.offset = 273.15;
  o.channels = {{"stroke", "m", stroke},
                {"force", "N", force},
                {"pressure", "Pa", daq::Calibration::FromRange16(0.0, 20e6)},
                {"temperature", "K", temperature}};
  return o;
}

//! A SocketCAN error frame with the given classes (CAN_ERR_*) and data bytes 1, 6 and 7.
inline daq::CanFrame ErrorFrame(canid_t classes, std::uint8_t controller = 0, std::uint8_t tec = 0, std::uint8_t rec = 0) {
  daq::CanFrame f;
  f.raw.can_id = CAN_ERR_FLAG | classes;
  f.raw.len = CAN_ERR_DLC;
  f.raw.data[1] = controller;
  f.raw.data[6] = tec;
  f.raw.data[7] = rec;
  return f;
}

//! Sets of counts (i, -i, 3i, 7) for i = first .. first + n - 1, as frames of `encoder`.
inline std::vector<daq::CanFrame> Ramp(daq::CanSampleEncoder& encoder, int first, int n) {
  std::vector<daq::CanFrame> frames;
  for (int i = first; i < first + n; ++i) {
    const std::int16_t set[] = {static_cast<std::int16_t>(i), static_cast<std::int16_t>(-i),
                                static_cast<std::int16_t>(3 * i), 7};
    encoder.Add(set, frames);
  }
  return frames;
}

}  // namespace strut::test
