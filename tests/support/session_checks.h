// Sessions compared field by field, for the tests of what the session files keep (on strut_daq).
#pragma once

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "strut/daq/session.h"

namespace strut::test {

//! `actual` has as many elements as `expected`, and `expect_same(expected[i], actual[i])` holds for each.
template <typename T, typename ExpectSame>
void ExpectSameEach(const std::vector<T>& expected, const std::vector<T>& actual, ExpectSame expect_same) {
  ASSERT_EQ(actual.size(), expected.size());
  for (std::size_t i = 0; i < expected.size(); ++i) expect_same(expected[i], actual[i]);
}

//! The channel's name, units, reference and every sample.
inline void ExpectSameChannel(const daq::Channel& expected, const daq::Channel& actual) {
  EXPECT_EQ(actual.name, expected.name);
  EXPECT_EQ(actual.units, expected.units);
  EXPECT_EQ(actual.reference, expected.reference);
  EXPECT_EQ(actual.samples, expected.samples);
}

//! Every field and sample of `actual` equals `expected`'s (a round trip through a file).
inline void ExpectSameExperiment(const daq::Experiment& expected, const daq::Experiment& actual) {
  SCOPED_TRACE("experiment " + expected.label);
  EXPECT_EQ(actual.label, expected.label);
  EXPECT_EQ(actual.kind, expected.kind);
  EXPECT_EQ(actual.status, expected.status);
  EXPECT_EQ(actual.sample_rate, expected.sample_rate);
  EXPECT_EQ(actual.frequency, expected.frequency);
  EXPECT_EQ(actual.amplitude, expected.amplitude);
  EXPECT_EQ(actual.static_position, expected.static_position);
  EXPECT_EQ(actual.waveform, expected.waveform);
  EXPECT_EQ(actual.periods, expected.periods);
  EXPECT_EQ(actual.group, expected.group);
  EXPECT_EQ(actual.drop_mass, expected.drop_mass);
  EXPECT_EQ(actual.impact_velocity, expected.impact_velocity);
  EXPECT_EQ(actual.time, expected.time);
  EXPECT_EQ(actual.extra_attributes, expected.extra_attributes);
  ExpectSameEach(expected.channels, actual.channels, ExpectSameChannel);
}

//! The session's own fields and every experiment, as ExpectSameExperiment.
inline void ExpectSameSession(const daq::Session& expected, const daq::Session& actual) {
  EXPECT_EQ(actual.format_version, expected.format_version);
  EXPECT_EQ(actual.created_utc, expected.created_utc);
  EXPECT_EQ(actual.damper_serial, expected.damper_serial);
  EXPECT_EQ(actual.rig, expected.rig);
  ExpectSameEach(expected.experiments, actual.experiments, ExpectSameExperiment);
}

}  // namespace strut::test
