// An instant of a damper model (unknowns, their rates, the input and its rates) and its residual,
// in doubles and in forward-mode jets, for the tests of the model's exact derivatives (on
// strut_ident_model).
#pragma once

#include <vector>

#include "strut/ident/autodiff.h"
#include "strut/ident/model.h"

namespace strut::test {

struct Instant {
  std::vector<double> x, xd, xdd;  //!< the unknowns and their first and second rates
  double u = 0, ud = 0, udd = 0;   //!< the input and its rates
};

//! The residual at `p` for the parameter values `theta`.
inline std::vector<double> ResidualAt(const ident::Model& model, const Instant& p, const std::vector<double>& theta) {
  std::vector<double> r(model.unknown_count());
  model.Residual<double>(p.x, p.xd, p.xdd, p.u, p.ud, p.udd, theta, r);
  return r;
}

//! Directions of ResidualJets: x, xd, xdd of every unknown (m each), u, u', u'', every parameter.
inline int JetDirections(const ident::Model& model) { return 3 * model.unknown_count() + 3 + model.parameter_count(); }

//! The residual at `p` with its exact derivatives along every direction of JetDirections, in that
//! order: x[j] is direction j, xd[j] m + j, xdd[j] 2m + j, u 3m, u' 3m + 1, u'' 3m + 2, theta[i] 3m + 3 + i.
inline std::vector<ident::Jet> ResidualJets(const ident::Model& model, const Instant& p,
                                            const std::vector<double>& theta) {
  using ident::MakeVariable;
  const int m = model.unknown_count(), np = model.parameter_count(), nd = JetDirections(model);
  std::vector<ident::Jet> x(m), xd(m), xdd(m), th(np), r(m);
  for (int j = 0; j < m; ++j) {
    x[j] = MakeVariable(p.x[j], nd, j);
    xd[j] = MakeVariable(p.xd[j], nd, m + j);
    xdd[j] = MakeVariable(p.xdd[j], nd, 2 * m + j);
  }
  const ident::Jet u = MakeVariable(p.u, nd, 3 * m), ud = MakeVariable(p.ud, nd, 3 * m + 1),
                   udd = MakeVariable(p.udd, nd, 3 * m + 2);
  for (int i = 0; i < np; ++i) th[i] = MakeVariable(theta[i], nd, 3 * m + 3 + i);
  model.Residual<ident::Jet>(x, xd, xdd, u, ud, udd, th, r);
  return r;
}

}  // namespace strut::test
