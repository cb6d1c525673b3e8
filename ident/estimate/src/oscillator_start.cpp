#include "strut/ident/initial_values.h"

#include <Eigen/Dense>
#include <cmath>
#include <complex>
#include <fmt/format.h>
#include <numbers>
#include <stdexcept>
#include <unsupported/Eigen/FFT>

namespace strut::ident {

ParameterSet OscillatorInitialValues(const Model& model, const std::vector<ExperimentData>& data,
                                     std::vector<std::string>* log) {
  if (!model.has_term("linear-oscillator"))
    throw std::invalid_argument(fmt::format("model '{}' is not a linear-oscillator model", model.composition()));
  if (data.empty()) throw std::invalid_argument("oscillator starting values: no experiments");
  ParameterSet values = model.defaults();
  const std::string y_name = model.output_channels()[0], u_name = model.output_channels()[1];
  const bool k2 = model.has_term("quadratic-stiffness"), k3 = model.has_term("cubic-stiffness");
  const bool d3 = model.has_term("cubic-damping");
  const bool u0 = model.has_term("input-offset"), y0 = model.has_term("output-offset");
  const bool constant = u0 || y0;
  // Columns: y'', y', y, [y^2], [y^3], [y'^3], [1].
  const int columns = 3 + k2 + k3 + d3 + constant;
  long rows = 0;
  for (const ExperimentData& d : data) {
    for (const std::string& c : {y_name, u_name})
      if (!d.channels.count(c))
        throw std::invalid_argument(fmt::format("{}: experiment '{}' has no '{}' channel", d.session, d.label, c));
    rows += d.channels.at(y_name).mean.size();
  }
  Eigen::MatrixXd a(rows, columns);
  Eigen::VectorXd b(rows);
  long row = 0;
  for (const ExperimentData& d : data) {
    const Eigen::VectorXd& y = d.channels.at(y_name).mean;
    const int count = static_cast<int>(y.size());
    const PeriodicSeries series = PeriodicSeries::Fit(y, d.frequency);
    const Eigen::VectorXd y2 = series.OnPhases(count, 2), y1 = series.OnPhases(count, 1);
    int col = 0;
    a.block(row, col++, count, 1) = y2;
    a.block(row, col++, count, 1) = y1;
    a.block(row, col++, count, 1) = y;
    if (k2) a.block(row, col++, count, 1) = y.array().square().matrix();
    if (k3) a.block(row, col++, count, 1) = y.array().cube().matrix();
    if (d3) a.block(row, col++, count, 1) = y1.array().cube().matrix();
    if (constant) a.block(row, col++, count, 1).setOnes();
    b.segment(row, count) = d.channels.at(u_name).mean;
    row += count;
  }
  // Equilibrate the columns: y'' is 1e5 times y.
  const Eigen::VectorXd norms = a.colwise().norm().transpose().cwiseMax(1e-300);
  const Eigen::VectorXd x = (a * norms.cwiseInverse().asDiagonal()).colPivHouseholderQr().solve(b).cwiseQuotient(norms);
  const double rms = std::sqrt((a * x - b).squaredNorm() / static_cast<double>(rows));
  int col = 0;
  const auto set = [&](int index, double value, const std::string& how) {
    const int position = values.position_of_index(index);
    values.values()[position] = value;
    if (log)
      log->push_back(fmt::format("{} {} = {:.6g} {}", values.spec(position).key(), values.spec(position).name, value, how));
  };
  const std::string how = fmt::format("(equation-error least squares over {} experiments, input rms residual {:.3g})",
                                      data.size(), rms);
  set(50, x[col++], how);
  set(51, x[col++], how);
  set(52, x[col++], how);
  if (k2) set(53, x[col++], how);
  if (k3) set(54, x[col++], how);
  if (d3) set(58, x[col++], how);
  if (u0) set(55, x[col], how);
  if (y0) set(56, u0 ? 0.0 : -x[col] / x[2], u0 ? "(the input offset takes the constant)" : "(from the fit's constant)");
  return values;
}

}  // namespace strut::ident
