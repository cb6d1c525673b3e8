// The simulated rig's acquisition module on CAN: the readings of the simulated sensors (16-bit
// ADC codes over each channel's range) leave as counts in the documented frames
// (docs/can-acquisition.md), so a daq::CanAcquisition at the other end of the transport receives
// what sim/ records directly, paced by the simulation clock that drives the SampleSink.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "strut/daq/can_acquisition.h"
#include "strut/sim/sensors.h"
#include "strut/sim/simulated_rig.h"

namespace strut::sim {

//! Stroke, force and pressure with the calibration of the sensors' 16-bit converters
//! (daq::Calibration::FromRange16 over each range): a count is the ADC code less 32768.
//! Throws std::invalid_argument when a sensor is not a 16-bit channel.
std::vector<daq::ChannelDescriptor> CanChannels(const SensorSet& sensors);

//! The module: a SampleSink target that sends every block's readings as sample frames of three
//! channels, with a status frame (marked simulated) every tenth of a second of samples.
class CanModule {
 public:
  //! `sample_rate`: the stream's one rate; every block must have it.
  CanModule(std::unique_ptr<daq::CanTransport> transport, const SensorSet& sensors, double sample_rate, bool fd = false,
            std::uint8_t module = 1);
  //! Sends the block's readings. Throws std::invalid_argument naming the experiment when its
  //! sample rate is not the stream's; daq::DeviceError when the transport fails.
  void Send(const SampleBlock& block);
  //! Sends the sets still queued (a partly filled CAN FD frame waits for its remaining sets).
  void Flush() { sender_.Flush(); }
  //! A SampleSink that calls Send; the module must outlive it.
  SampleSink sink() {
    return [this](const SampleBlock& b) { Send(b); };
  }
  //! What a receiver needs: layout, rate and channels (stale_after and block size left default).
  daq::CanAcquisitionOptions ReceiverOptions() const;
  std::uint64_t sets_sent() const { return sender_.encoder().next_index(); }

 private:
  daq::CanAcquisitionSender sender_;
  std::vector<daq::ChannelDescriptor> channels_;
  double sample_rate_;
};

}  // namespace strut::sim
