// Sessions of the QC lot's units (study/lot.h) through the QC matrix on the simulated rig, for the
// QC tests (strut_test_lot_sessions, on strut_study: apart from strut_test_sessions, so that tests
// of the layers under study do not link it).
#pragma once

#include <cstdint>

#include "strut/daq/session.h"
#include "strut/study/lot.h"

namespace strut::test {

//! The lot's unit `seed` with `defect`, through the QC matrix on the simulated rig.
daq::Session QcSession(std::uint64_t seed, study::Defect defect, std::uint64_t noise_seed);

}  // namespace strut::test
