#include "lot_sessions.h"

#include "strut/sim/simulated_rig.h"

namespace strut::test {

daq::Session QcSession(std::uint64_t seed, study::Defect defect, std::uint64_t noise_seed) {
  const sim::Truth unit = study::MakeDefective(study::LotUnit(seed), defect, study::LotReference(), seed);
  sim::RigRunOptions run;
  run.seed = noise_seed;
  return sim::SimulatedRig(unit).RunMatrix(study::QcMatrix(), run);
}

}  // namespace strut::test
