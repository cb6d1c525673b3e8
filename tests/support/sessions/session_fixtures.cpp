#include "session_fixtures.h"

#include "strut/daq/session.h"
#include "strut/ident/model.h"
#include "strut/sim/draw.h"
#include "strut/sim/periodic_session.h"
#include "strut/sim/simulated_rig.h"

namespace strut::test {

std::vector<rig::MatrixEntry> StandardExperiments(const std::string& labels) {
  std::vector<rig::MatrixEntry> matrix;
  for (const auto& e : rig::StandardMatrix())
    if (labels.find(e.label) != std::string::npos) matrix.push_back(e);
  return matrix;
}

ident::FitData SimulatedFitData(const std::string& truth_model, const std::string& changes, unsigned seed, int n) {
  const ident::Model model = ident::Model::Build(truth_model, ident::Causality::kStrokeInput);
  ident::ParameterSet truth = model.defaults();
  if (!changes.empty()) truth.apply_assignments(changes);
  sim::PeriodicSessionOptions options;
  options.seed = seed;
  const daq::Session session = sim::SimulatePeriodicSession(truth_model, truth.values(), rig::StandardMatrix(), options);
  return ident::PrepareFitData(session, "simulated", model, n);
}

ident::SessionFitOptions FitOptionsOnGrid(const std::string& composition, int n) {
  ident::SessionFitOptions options;
  options.composition = composition;
  options.estimator.n = n;
  return options;
}

void WriteTwoDofSession(const std::string& path, const std::string& labels, const ident::ParameterSet& truth) {
  daq::WriteSession(path, sim::SimulatePeriodicSession("2dof", truth.values(), StandardExperiments(labels), {}));
}

void WriteTwoDofSession(const std::string& path, const std::string& labels) {
  WriteTwoDofSession(path, labels, ident::Model::Build("2dof", ident::Causality::kStrokeInput).defaults());
}

sim::Truth DrawnIdealUnit(std::uint64_t seed) {
  return sim::DrawUnit(sim::WithIdealRig(sim::DefaultTruth()), sim::UnitDraw{}, seed);
}

daq::Session DrawnUnitSession(std::uint64_t seed) {
  const sim::SimulatedRig rig(DrawnIdealUnit(seed));
  sim::RigRunOptions run;
  run.seed = seed;
  return rig.RunMatrix(rig::StandardMatrixPlan(), run);
}

}  // namespace strut::test
