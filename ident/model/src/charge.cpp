#include "strut/ident/charge.h"

#include <cmath>

namespace strut::ident {

double ChargePressure(const Model& model, const std::vector<double>& theta) {
  const int offset = model.defaults().position_of_index(12);
  const std::vector<double> x = model.StaticEquilibrium(offset >= 0 ? theta[offset] : 0.0, theta);
  for (std::size_t i = 0; i < model.states().size(); ++i)
    if (model.states()[i].name == "pressure") return x[1 + i];
  throw ModelError("the model has no gas pressure");
}

void SetCharge(const Model& model, std::vector<double>& theta, double p0) {
  const ParameterSet& d = model.defaults();
  if (const int ref = d.position_of_index(27); ref >= 0) theta[ref] = p0;  // compliance reference
  const int scale = d.position_of_index(5);
  for (int i = 0; i < 20; ++i) {
    const double p = ChargePressure(model, theta);
    theta[scale] *= p0 / p;
    if (std::abs(p / p0 - 1.0) < 1e-12) break;
  }
}

}  // namespace strut::ident
