#include "strut/ident/grid.h"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <numbers>
#include <stdexcept>

namespace strut::ident {

std::string_view ToString(Scheme s) {
  switch (s) {
    case Scheme::kBackward2: return "backward2";
    case Scheme::kCentral2: return "central2";
    case Scheme::kCentral4: return "central4";
    case Scheme::kSpectral: return "spectral";
  }
  return "?";
}

Scheme ParseScheme(std::string_view text) {
  for (Scheme s : {Scheme::kBackward2, Scheme::kCentral2, Scheme::kCentral4, Scheme::kSpectral})
    if (ToString(s) == text) return s;
  throw std::invalid_argument(
      fmt::format("unknown scheme '{}': use backward2, central2, central4 or spectral", text));
}

Stencil Stencil::For(Scheme scheme, int n) {
  Stencil s;
  const double h = 1.0 / n;
  const auto set = [&](int kmin, int kmax, std::vector<double> first, std::vector<double> second, double p1,
                       double p2) {
    s.kmin = kmin;
    s.kmax = kmax;
    s.first = std::move(first);
    s.second = std::move(second);
    for (double& c : s.first) c /= p1;
    for (double& c : s.second) c /= p2;
  };
  switch (scheme) {
    case Scheme::kBackward2:  // eqs. 8, 9: offsets -3..0
      set(-3, 0, {0.0, 0.5, -2.0, 1.5}, {-1.0, 4.0, -5.0, 2.0}, h, h * h);
      break;
    case Scheme::kCentral2:
      set(-1, 1, {-0.5, 0.0, 0.5}, {1.0, -2.0, 1.0}, h, h * h);
      break;
    case Scheme::kCentral4:
      set(-2, 2, {1.0 / 12, -8.0 / 12, 0.0, 8.0 / 12, -1.0 / 12},
          {-1.0 / 12, 16.0 / 12, -30.0 / 12, 16.0 / 12, -1.0 / 12}, h, h * h);
      break;
    case Scheme::kSpectral: {
      // Fourier differentiation on a period of 1: circulant, so one row gives every row.
      s.kmin = -((n - 1) / 2);
      s.kmax = s.kmin + n - 1;
      Eigen::VectorXd d1(n);
      for (int j = 0; j < n; ++j) {
        if (j == 0) {
          d1[j] = 0.0;
          continue;
        }
        const double sign = (j % 2 == 0) ? 1.0 : -1.0;
        const double x = std::numbers::pi * j / n;
        // column j of row 0: derivative weight of x_j at x_0 (antisymmetric in j).
        d1[j] = -(n % 2 == 0 ? std::numbers::pi * sign / std::tan(x) : std::numbers::pi * sign / std::sin(x));
      }
      // Second derivative as the square of the first (circulant convolution).
      Eigen::VectorXd d2 = Eigen::VectorXd::Zero(n);
      for (int j = 0; j < n; ++j)
        for (int l = 0; l < n; ++l) d2[j] += d1[l] * d1[((j - l) % n + n) % n];
      s.first.resize(n);
      s.second.resize(n);
      for (int k = s.kmin; k <= s.kmax; ++k) {
        const int j = ((k % n) + n) % n;
        s.first[k - s.kmin] = d1[j];
        s.second[k - s.kmin] = d2[j];
      }
      break;
    }
  }
  return s;
}

namespace {

// Weights w_j of sum_j w_j x(t_j) ~ x^(derivative)(t0) from the nodes t_j (offsets from t0): the
// Lagrange interpolant's derivative, by the moment conditions sum_j w_j t_j^p / p! = [p == derivative].
void DerivativeWeights(const std::vector<double>& nodes, int derivative, std::vector<double>& weights) {
  const int count = static_cast<int>(nodes.size());
  double scale = 0.0;
  for (double t : nodes) scale = std::max(scale, std::abs(t));
  Eigen::MatrixXd moments(count, count);
  for (int p = 0; p < count; ++p)
    for (int j = 0; j < count; ++j) moments(p, j) = std::pow(nodes[j] / scale, p) / std::tgamma(p + 1.0);
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(count);
  rhs[derivative] = 1.0;
  const Eigen::VectorXd w = moments.fullPivLu().solve(rhs) / std::pow(scale, derivative);
  weights.assign(w.data(), w.data() + count);
}

}  // namespace

Stencil Stencil::For(Scheme scheme, const std::vector<double>& phases) {
  const int n = static_cast<int>(phases.size());
  if (scheme == Scheme::kSpectral)
    throw std::invalid_argument("periodic solver: the spectral scheme needs an equidistant grid");
  if (n < 8) throw std::invalid_argument(fmt::format("periodic solver needs n >= 8, got {}", n));
  Stencil s = For(scheme, n);
  for (int mu = 0; mu < n; ++mu)
    if (!(phases[mu] >= 0.0 && phases[mu] < 1.0) || (mu > 0 && !(phases[mu] > phases[mu - 1])))
      throw std::invalid_argument(
          fmt::format("periodic solver: grid phases must increase strictly in [0, 1) (point {}: {})", mu, phases[mu]));
  // The offsets each derivative reads (the equidistant stencil's nonzero ones).
  std::vector<int> first_offsets, second_offsets;
  for (int k = s.kmin; k <= s.kmax; ++k) {
    if (s.first[k - s.kmin] != 0.0 || k == 0) first_offsets.push_back(k);  // central: x_mu too
    if (s.second[k - s.kmin] != 0.0) second_offsets.push_back(k);
  }
  const int width = s.kmax - s.kmin + 1;
  s.first_at.assign(static_cast<std::size_t>(n) * width, 0.0);
  s.second_at.assign(static_cast<std::size_t>(n) * width, 0.0);
  const auto offset_phase = [&](int mu, int k) {  // phase of point mu + k, unwrapped around mu
    const int nu = mu + k;
    if (nu < 0) return phases[nu + n] - 1.0;
    if (nu >= n) return phases[nu - n] + 1.0;
    return phases[nu];
  };
  std::vector<double> nodes, weights;
  for (int mu = 0; mu < n; ++mu)
    for (int derivative = 1; derivative <= 2; ++derivative) {
      const std::vector<int>& offsets = derivative == 1 ? first_offsets : second_offsets;
      nodes.clear();
      for (int k : offsets) nodes.push_back(offset_phase(mu, k) - phases[mu]);
      DerivativeWeights(nodes, derivative, weights);
      std::vector<double>& at = derivative == 1 ? s.first_at : s.second_at;
      for (std::size_t j = 0; j < offsets.size(); ++j)
        at[static_cast<std::size_t>(mu) * width + (offsets[j] - s.kmin)] = weights[j];
    }
  return s;
}


PhaseInterpolation PhaseInterpolation::Cubic(const std::vector<double>& grid, int n, std::span<const double> targets) {
  if (!grid.empty() && static_cast<int>(grid.size()) != n)
    throw std::invalid_argument("phase interpolation: the grid's phases do not match its size");
  if (n < 4) throw std::invalid_argument("phase interpolation needs at least 4 grid points");
  const auto phase = [&](int j) { return grid.empty() ? static_cast<double>(j) / n : grid[j]; };
  PhaseInterpolation p;
  p.taps.resize(targets.size());
  p.weights.resize(targets.size());
  for (std::size_t i = 0; i < targets.size(); ++i) {
    const double tau = targets[i] - std::floor(targets[i]);
    int j0;
    if (grid.empty()) {
      j0 = static_cast<int>(std::floor(tau * n)) % n;
    } else {
      j0 = static_cast<int>(std::upper_bound(grid.begin(), grid.end(), tau) - grid.begin()) - 1;
      if (j0 < 0) j0 = n - 1;  // before the first point: the interval from the last one, wrapped
    }
    double x[4];
    for (int k = 0; k < 4; ++k) {
      const int j = j0 + k - 1;
      const int wrapped = (j % n + n) % n;
      p.taps[i][k] = wrapped;
      x[k] = phase(wrapped) + std::floor(static_cast<double>(j) / n);  // unwrapped around j0
    }
    double t = tau;  // onto the unwrapped interval x[1] .. x[2] (it may sit a period away)
    if (t < x[1] - 0.5) t += 1.0;
    if (t > x[2] + 0.5) t -= 1.0;
    for (int k = 0; k < 4; ++k) {
      double w = 1.0;
      for (int l = 0; l < 4; ++l)
        if (l != k) w *= (t - x[l]) / (x[k] - x[l]);
      p.weights[i][k] = w;
    }
  }
  return p;
}

Eigen::MatrixXd PhaseInterpolation::Columns(const Eigen::MatrixXd& grid) const {
  Eigen::MatrixXd out(static_cast<Eigen::Index>(taps.size()), grid.cols());
  for (Eigen::Index c = 0; c < grid.cols(); ++c) {
    const double* g = grid.col(c).data();
    double* o = out.col(c).data();
    for (std::size_t i = 0; i < taps.size(); ++i)
      o[i] = weights[i][0] * g[taps[i][0]] + weights[i][1] * g[taps[i][1]] + weights[i][2] * g[taps[i][2]] +
             weights[i][3] * g[taps[i][3]];
  }
  return out;
}

Eigen::MatrixXd PhaseInterpolation::Rows(const Eigen::MatrixXd& rows) const {
  return Columns(rows.transpose()).transpose();
}

PhaseProducts::PhaseProducts(const PhaseInterpolation& map, int n) {
  std::vector<Eigen::Triplet<double>> entries;
  for (std::size_t i = 0; i < map.taps.size(); ++i)
    for (int k = 0; k < 4; ++k)
      if (map.weights[i][k] != 0.0) entries.emplace_back(map.taps[i][k], static_cast<int>(i), map.weights[i][k]);
  transpose_map_.resize(n, static_cast<Eigen::Index>(map.taps.size()));
  transpose_map_.setFromTriplets(entries.begin(), entries.end());
  const Eigen::SparseMatrix<double> normal = transpose_map_ * transpose_map_.transpose();
  const Eigen::SimplicialLLT<Eigen::SparseMatrix<double>> llt(normal);
  if (llt.info() != Eigen::Success)
    throw std::invalid_argument("phase products: a grid point carries no weight at the targets");
  lower_ = llt.matrixL();
  order_ = llt.permutationP();
  upper_ordered_ = Eigen::SparseMatrix<double, Eigen::RowMajor>(lower_.transpose()) * order_;
}

Eigen::MatrixXd PhaseProducts::Columns(const Eigen::MatrixXd& grid) const {
  return Eigen::MatrixXd(upper_ordered_ * grid);
}

Eigen::VectorXd PhaseProducts::Vector(const Eigen::VectorXd& at_targets) const {
  return lower_.triangularView<Eigen::Lower>().solve(Eigen::VectorXd(order_ * (transpose_map_ * at_targets)));
}

Eigen::VectorXd PhaseProducts::GridWeights(const Eigen::VectorXd& column) const {
  return order_.transpose() * Eigen::VectorXd(lower_ * column);
}


Eigen::MatrixXd PeriodSynchronousSamples(std::span<const double> samples, double sample_rate, double frequency,
                                         long periods, int n) {
  if (periods < 1 || !(sample_rate > 0) || !(frequency > 0) || n < 4)
    throw std::invalid_argument("period averaging needs periods >= 1, positive rates and n >= 4");
  const double per_period = sample_rate / frequency;
  const double total = per_period * periods;
  if (samples.size() + 1 < static_cast<std::size_t>(std::floor(total)) || samples.empty())
    throw std::invalid_argument(
        fmt::format("record has {} samples, {} periods need {:.0f}", samples.size(), periods, total));
  const long count = static_cast<long>(samples.size());
  Eigen::MatrixXd values(n, periods);
  for (long k = 0; k < periods; ++k)
    for (int mu = 0; mu < n; ++mu) {
      const double position = (k + static_cast<double>(mu) / n) * per_period;
      const long i0 = static_cast<long>(std::floor(position));
      const double w = position - i0;
      values(mu, k) = (1.0 - w) * samples[i0 % count] + w * samples[(i0 + 1) % count];
    }
  return values;
}

Eigen::MatrixXd PeriodicResample(const Eigen::MatrixXd& rows, int points) {
  const int n = static_cast<int>(rows.cols());
  Eigen::MatrixXd out(rows.rows(), points);
  const auto at = [&](int i) { return rows.col(((i % n) + n) % n); };
  for (int mu = 0; mu < points; ++mu) {
    const double x = static_cast<double>(mu) * n / points;
    const int i = static_cast<int>(std::floor(x));
    const double w = x - i;
    const auto p0 = at(i - 1), p1 = at(i), p2 = at(i + 1), p3 = at(i + 2);
    out.col(mu) = p1 + 0.5 * w * (p2 - p0 + w * (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3 + w * (3.0 * (p1 - p2) + p3 - p0)));
  }
  return out;
}

}  // namespace strut::ident
