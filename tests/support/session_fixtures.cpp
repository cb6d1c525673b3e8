// Session fixtures made by the simulator: the tests that fit or report need recorded sessions, and
// the transient simulation is their independent source.
#include "test_support.h"

#include "strut/daq/session.h"
#include "strut/ident/model.h"
#include "strut/rig/test_matrix.h"
#include "strut/sim/periodic_session.h"

namespace strut::test {

void WriteTwoDofSession(const std::string& path, const std::string& labels) {
  std::vector<rig::MatrixEntry> matrix;
  for (const auto& e : rig::StandardMatrix())
    if (labels.find(e.label) != std::string::npos) matrix.push_back(e);
  const ident::ParameterSet truth =
      ident::Model::Build("2dof", ident::Causality::kStrokeInput).defaults();
  daq::WriteSession(path, sim::SimulatePeriodicSession("2dof", truth.values(), matrix, {}));
}

}  // namespace strut::test
