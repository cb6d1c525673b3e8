// The IDA tolerances the tests' reference integrations run at (on strut_sim).
#pragma once

#include "strut/sim/transient.h"

namespace strut::test {

//! Relative tolerance 1e-11 and absolute tolerances 1e-3 of each unknown's scale, so that the
//! relative one rules: an integration far more accurate than what it is compared with.
inline sim::TransientOptions ReferenceTolerances() {
  sim::TransientOptions options;
  options.rtol = 1e-11;
  options.atol_factor = 1e-3;
  return options;
}

}  // namespace strut::test
