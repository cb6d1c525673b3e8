// The simulated rig's acquisition module on CAN (can_module.h).
#include "strut/sim/can_module.h"

#include <fmt/format.h>

#include <cmath>
#include <stdexcept>

namespace strut::sim {

std::vector<daq::ChannelDescriptor> CanChannels(const SensorSet& sensors) {
  std::vector<daq::ChannelDescriptor> channels;
  for (const auto& [name, s] : {std::pair<const char*, const SensorOptions&>{"stroke", sensors.stroke},
                                {"force", sensors.force}, {"pressure", sensors.pressure}}) {
    if (s.bits != 16)
      throw std::invalid_argument(fmt::format("CAN module: the {} sensor has a {}-bit converter; the frames carry 16 bits",
                                              name, s.bits));
    channels.push_back({name, s.units, daq::Calibration::FromRange16(s.range_min, s.range_max)});
  }
  return channels;
}

namespace {
daq::CanFrameLayout Layout(bool fd, std::uint8_t module) {
  daq::CanFrameLayout layout;
  layout.channels = 3;
  layout.fd = fd;
  layout.module = module;
  return layout;
}
}  // namespace

CanModule::CanModule(std::unique_ptr<daq::CanTransport> transport, const SensorSet& sensors, double sample_rate, bool fd,
                     std::uint8_t module)
    : sender_(std::move(transport), Layout(fd, module), daq::StatusEvery(sample_rate)),
      channels_(CanChannels(sensors)),
      sample_rate_(sample_rate) {
  sender_.set_status(daq::can_status::kSimulated);
}

void CanModule::Send(const SampleBlock& block) {
  if (std::abs(block.sample_rate - sample_rate_) > 1e-9 * sample_rate_)
    throw std::invalid_argument(fmt::format("CAN module: experiment {} is sampled at {} Hz, the stream at {} Hz",
                                            block.experiment, block.sample_rate, sample_rate_));
  const std::vector<double>* readings[] = {&block.stroke, &block.force, &block.pressure};
  std::int16_t set[3];
  for (std::size_t i = 0; i < block.stroke.size(); ++i) {
    for (int c = 0; c < 3; ++c) set[c] = channels_[c].calibration.ToCounts16((*readings[c])[i]);
    sender_.Add(set);
  }
  sender_.Flush();
}

daq::CanAcquisitionOptions CanModule::ReceiverOptions() const {
  daq::CanAcquisitionOptions o;
  o.layout = sender_.encoder().layout();
  o.sample_rate = sample_rate_;
  o.channels = channels_;
  return o;
}

}  // namespace strut::sim
