#include "strut/ident/periodic.h"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <numbers>
#include <spdlog/spdlog.h>

namespace strut::ident {

namespace {

// The scheme's stencil on an input's grid: its phases, or n equidistant points.
Stencil GridStencil(Scheme scheme, const PeriodicInput& grid) {
  return grid.phases.empty() ? Stencil::For(scheme, static_cast<int>(grid.values.size()))
                             : Stencil::For(scheme, grid.phases);
}

}  // namespace

PeriodicInput PeriodicInput::Sine(double frequency, double mean, double amplitude, int n) {
  PeriodicInput in;
  in.frequency = frequency;
  in.values.resize(n);
  for (int mu = 0; mu < n; ++mu) in.values[mu] = mean + amplitude * std::sin(2.0 * std::numbers::pi * mu / n);
  return in;
}

PeriodicInput PeriodicInput::FromRecord(std::span<const double> samples, double sample_rate, double frequency,
                                        long periods, int n) {
  const Eigen::VectorXd mean = PeriodSynchronousSamples(samples, sample_rate, frequency, periods, n).rowwise().mean();
  return PeriodicInput{frequency, std::vector<double>(mean.data(), mean.data() + n)};
}

bool PeriodicSolverOptions::IsValid(std::string* error) const {
  const auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (max_iterations < 1) return fail("max_iterations must be at least 1");
  if (max_halvings < 0) return fail("max_halvings must not be negative");
  if (!(tolerance > 0)) return fail("tolerance must be positive");
  if (start_up_periods < 0) return fail("start_up_periods must not be negative");
  if (coarse_points < 0) return fail("coarse_points must not be negative");
  if (!(reuse_contraction >= 0 && reuse_contraction < 1)) return fail("reuse_contraction must be in [0, 1)");
  return true;
}

std::vector<double> PeriodicSolution::time() const {
  std::vector<double> t(n);
  const bool at_phases = static_cast<int>(input.phases.size()) == n;
  for (int mu = 0; mu < n; ++mu) t[mu] = (at_phases ? input.phases[mu] : static_cast<double>(mu) / n) / frequency;
  return t;
}

Eigen::VectorXd PeriodicSolution::channel(std::string_view name) const {
  for (std::size_t c = 0; c < channels.size(); ++c)
    if (channels[c] == name) return outputs.row(static_cast<int>(c)).transpose();
  throw std::out_of_range(fmt::format("periodic solution has no channel '{}'", name));
}

std::optional<std::string> PhysicalViolation(const Model& model, const PeriodicSolution& solution,
                                             std::span<const double> theta) {
  const int n = solution.n, m = model.unknown_count();
  if (static_cast<int>(theta.size()) != model.parameter_count() || n <= 0 || solution.unknowns.rows() != m ||
      solution.unknowns.cols() != n || static_cast<int>(solution.input.values.size()) != n ||
      solution.outputs.cols() != n || solution.outputs.rows() != static_cast<int>(solution.channels.size()))
    throw std::invalid_argument("PhysicalViolation: the solution or the parameters do not fit the model");
  const auto at = [&](int mu) { return solution.frequency > 0 ? mu / (n * solution.frequency) : 0.0; };
  // The worst (lowest, or a non-finite) value of a row against a lower bound it must exceed.
  const auto check_above = [&](const auto& value_at, double bound, std::string_view what, std::string_view unit,
                               std::string_view rule) -> std::optional<std::string> {
    int worst = -1;
    for (int mu = 0; mu < n; ++mu) {
      const double v = value_at(mu);
      if (!std::isfinite(v)) return fmt::format("{} is not finite at t = {:.4g} s", what, at(mu));
      if (v <= bound && (worst < 0 || v < value_at(worst))) worst = mu;
    }
    if (worst < 0) return std::nullopt;
    return fmt::format("{} {:.4g}{}{} at t = {:.4g} s ({})", what, value_at(worst), unit.empty() ? "" : " ", unit,
                       at(worst), rule);
  };
  const auto row = [&](std::string_view name) {
    for (std::size_t c = 0; c < solution.channels.size(); ++c)
      if (solution.channels[c] == name) return static_cast<int>(c);
    return -1;
  };
  if (const int p = row("pressure"); p >= 0)
    if (auto v = check_above([&](int mu) { return solution.outputs(p, mu); }, 0.0, "absolute gas pressure", "Pa",
                             "must be positive"))
      return v;
  if (const int t = row("temperature"); t >= 0)
    if (auto v = check_above([&](int mu) { return solution.outputs(t, mu); }, 0.0, "gas temperature", "K",
                             "must be positive"))
      return v;
  const std::vector<std::string> channels = model.output_channels();
  if (channels.empty() || channels[0] != "stroke") return std::nullopt;  // not a damper
  // The true stroke q: the unknown under force input, measured stroke - theta12 under stroke input.
  const int offset = model.defaults().position_of_index(12);
  const auto stroke = [&](int mu) {
    if (model.causality() == Causality::kForceInput) return solution.unknowns(0, mu);
    return solution.input.values[mu] - (offset >= 0 ? theta[offset] : 0.0);
  };
  if (const int volume = model.defaults().position_of_index(6); volume >= 0)
    if (auto v = check_above([&](int mu) { return 1.0 + theta[volume] * stroke(mu); }, 0.0,
                             "relative gas volume 1 + theta6 q =", "",
                             fmt::format("must be positive; theta6 = {:.4g} 1/m", theta[volume])))
      return v;
  if (model.causality() == Causality::kForceInput) {
    const double low = -kDamperStrokeMargin, high = kDamperStroke + kDamperStrokeMargin;
    for (int mu = 0; mu < n; ++mu) {
      const double q = stroke(mu);
      if (!std::isfinite(q)) return fmt::format("stroke is not finite at t = {:.4g} s", at(mu));
    }
    int worst = 0;
    for (int mu = 1; mu < n; ++mu)
      if (std::max(low - stroke(mu), stroke(mu) - high) > std::max(low - stroke(worst), stroke(worst) - high))
        worst = mu;
    const double q = stroke(worst);
    if (q < low || q > high)
      return fmt::format("stroke {:.4g} m at t = {:.4g} s (outside the damper, 0 .. {} m with a {} m margin)", q,
                         at(worst), kDamperStroke, kDamperStrokeMargin);
  }
  return std::nullopt;
}

PeriodicSolver::PeriodicSolver(Model model, PeriodicSolverOptions options)
    : model_(std::move(model)), options_(options) {
  std::string error;
  if (!options_.IsValid(&error)) throw std::invalid_argument("periodic solver options: " + error);
  const int m = model_.unknown_count();
  equation_weight_.resize(m);
  for (int j = 0; j < m; ++j) equation_weight_[j] = 1.0 / model_.equation_scale(j);
}

void PeriodicSolver::Prepare(const PeriodicInput& grid) {
  const int n = static_cast<int>(grid.values.size());
  if (n == prepared_n_ && grid.phases == prepared_phases_) return;
  const int minimum = options_.scheme == Scheme::kSpectral ? 4 : 8;
  if (n < minimum) throw std::invalid_argument(fmt::format("periodic solver needs n >= {}, got {}", minimum, n));
  if (!grid.phases.empty() && static_cast<int>(grid.phases.size()) != n)
    throw std::invalid_argument(
        fmt::format("periodic solver: the input has {} values but {} grid phases", n, grid.phases.size()));
  stencil_ = GridStencil(options_.scheme, grid);
  jacobian_ = CyclicBlockBanded(n, model_.unknown_count(), stencil_.kmin, stencil_.kmax);
  prepared_n_ = n;
  prepared_phases_ = grid.phases;
  rated_directions_.resize(0, 0);
}

namespace {

// Time derivatives (real time) of a periodic grid function at point mu (one point, for marching).
struct Rates {
  double first, second;
};

template <class Row>
Rates RatesAt(const Stencil& s, const Row& values, int mu, int n, double frequency) {
  double d1 = 0.0, d2 = 0.0;
  for (int k = s.kmin; k <= s.kmax; ++k) {
    int nu = mu + k;
    if (nu < 0) nu += n;
    if (nu >= n) nu -= n;
    const double v = values(nu);
    d1 += s.First(mu, k) * v;
    d2 += s.Second(mu, k) * v;
  }
  return {d1 * frequency, d2 * frequency * frequency};
}

// First and second time derivatives of every row of z at every point: whole shifted columns per
// stencil offset, so the work is a few vector sweeps rather than an indexed loop per point.
void GridRates(const Stencil& s, const Eigen::MatrixXd& z, double frequency, Eigen::MatrixXd& first,
               Eigen::MatrixXd& second) {
  const int n = static_cast<int>(z.cols());
  const Eigen::Index m = z.rows();
  first.setZero(m, n);
  second.setZero(m, n);
  // Column-major: the columns mu + shift for mu = 0 .. n - shift - 1 are one contiguous run, and
  // so are the wrapped ones; each run is read once for both derivatives.
  const auto add = [&](Eigen::Index to, Eigen::Index from, Eigen::Index columns, double c1, double c2) {
    const double* src = z.data() + from * m;
    double* d1 = first.data() + to * m;
    double* d2 = second.data() + to * m;
    for (Eigen::Index i = 0; i < columns * m; ++i) {
      const double v = src[i];
      d1[i] += c1 * v;
      d2[i] += c2 * v;
    }
  };
  if (!s.equidistant()) {  // each point its own weights
    const int width = s.kmax - s.kmin + 1;
    const double f2 = frequency * frequency;
    for (int mu = 0; mu < n; ++mu) {
      double* d1 = first.data() + static_cast<Eigen::Index>(mu) * m;
      double* d2 = second.data() + static_cast<Eigen::Index>(mu) * m;
      const double* w1 = s.first_at.data() + static_cast<std::size_t>(mu) * width;
      const double* w2 = s.second_at.data() + static_cast<std::size_t>(mu) * width;
      for (int k = s.kmin; k <= s.kmax; ++k) {
        const double c1 = w1[k - s.kmin] * frequency, c2 = w2[k - s.kmin] * f2;
        int nu = mu + k;
        if (nu < 0) nu += n;
        else if (nu >= n) nu -= n;
        const double* src = z.data() + static_cast<Eigen::Index>(nu) * m;
        for (Eigen::Index i = 0; i < m; ++i) {
          d1[i] += c1 * src[i];
          d2[i] += c2 * src[i];
        }
      }
    }
    return;
  }
  for (int k = s.kmin; k <= s.kmax; ++k) {
    const double c1 = s.first[k - s.kmin] * frequency, c2 = s.second[k - s.kmin] * frequency * frequency;
    if (c1 == 0.0 && c2 == 0.0) continue;
    const int shift = ((k % n) + n) % n;  // column mu reads column (mu + shift) mod n
    add(0, shift, n - shift, c1, c2);
    if (shift > 0) add(n - shift, 0, shift, c1, c2);
  }
}

}  // namespace

namespace {

// Residuals of a batch of grid points and their derivatives with respect to the unknowns and their
// rates, scaled like G: r, dr/dx, dr/dx', dr/dx'' per point. J is the Jet type that carries the
// directions (each unknown and the rates its equations use).
template <class J>
struct Linearization {
  static constexpr int kBatch = 32;
  Linearization(const Model& model, std::span<const double> theta, const Eigen::VectorXd& weight)
      : model(model), weight(weight), m(model.unknown_count()) {
    first_direction.assign(m + 1, 0);
    order.resize(m);
    for (int j = 0; j < m; ++j) {
      order[j] = model.derivative_order(j);
      first_direction[j + 1] = first_direction[j] + order[j] + 1;
    }
    using Derivatives = typename J::DerType;
    directions = Derivatives::RowsAtCompileTime == Eigen::Dynamic ? first_direction[m]
                                                                 : int(Derivatives::RowsAtCompileTime);
    for (double t : theta) theta_jet.push_back(Constant(t));
    for (auto* v : {&x, &xd, &xdd, &residual}) v->resize(static_cast<std::size_t>(kBatch) * m);
    for (auto* v : {&u, &ud, &udd}) v->resize(kBatch);
    // The directions are the same at every point of every batch: set once, Load writes values only.
    using Derivatives = typename J::DerType;
    for (int k = 0; k < kBatch; ++k) {
      for (int j = 0; j < m; ++j) {
        const int d0 = first_direction[j];
        const std::size_t i = static_cast<std::size_t>(k) * m + j;
        x[i] = J(0.0, Derivatives::Unit(directions, d0));
        xd[i] = order[j] >= 1 ? J(0.0, Derivatives::Unit(directions, d0 + 1)) : Constant(0.0);
        xdd[i] = order[j] >= 2 ? J(0.0, Derivatives::Unit(directions, d0 + 2)) : Constant(0.0);
      }
      u[k] = ud[k] = udd[k] = Constant(0.0);
    }
    r.resize(m, kBatch);
    rx.resize(m, m * kBatch);
    rxd.resize(m, m * kBatch);
    rxdd.resize(m, m * kBatch);
  }
  // All Jets carry every direction (see autodiff.h).
  J Constant(double v) const { return J(v, J::DerType::Zero(directions)); }

  //! Point k of the batch: the unknowns, their rates, and the input with its rates.
  void Load(int k, const double* z, const double* zd, const double* zdd, double input, double input_rate,
            double input_accel) {
    for (int j = 0; j < m; ++j) {
      const std::size_t i = static_cast<std::size_t>(k) * m + j;
      x[i].value() = z[j];
      xd[i].value() = zd[j];
      xdd[i].value() = zdd[j];
    }
    u[k].value() = input;
    ud[k].value() = input_rate;
    udd[k].value() = input_accel;
  }

  //! Evaluates the first `count` loaded points.
  void Evaluate(int count) {
    const std::size_t values = static_cast<std::size_t>(count) * m;
    model.Residuals<J>(std::span<const J>(x.data(), values), std::span<const J>(xd.data(), values),
                       std::span<const J>(xdd.data(), values), std::span<const J>(u.data(), count),
                       std::span<const J>(ud.data(), count), std::span<const J>(udd.data(), count), theta_jet,
                       std::span<J>(residual.data(), values));
    for (int k = 0; k < count; ++k)
      for (int i = 0; i < m; ++i) {
        const J& res = residual[static_cast<std::size_t>(k) * m + i];
        const double scale = weight[i];
        const auto& d = res.derivatives();
        r(i, k) = res.value() * scale;
        for (int j = 0; j < m; ++j) {
          const int d0 = first_direction[j];
          rx(i, k * m + j) = d[d0] * scale;
          rxd(i, k * m + j) = order[j] >= 1 ? d[d0 + 1] * scale : 0.0;
          rxdd(i, k * m + j) = order[j] >= 2 ? d[d0 + 2] * scale : 0.0;
        }
      }
  }
  auto Rx(int k) const { return rx.middleCols(k * m, m); }
  auto Rxd(int k) const { return rxd.middleCols(k * m, m); }
  auto Rxdd(int k) const { return rxdd.middleCols(k * m, m); }

  const Model& model;
  const Eigen::VectorXd& weight;
  const int m;
  std::vector<int> first_direction, order;
  int directions = 0;
  std::vector<J> theta_jet, x, xd, xdd, u, ud, udd, residual;
  Eigen::MatrixXd r;             //!< m x batch
  Eigen::MatrixXd rx, rxd, rxdd;  //!< m x (m batch): point k's block in columns k m .. k m + m - 1
};

// Directions a Linearization needs: each unknown and the rates its equations use.
int LinearizationDirections(const Model& model) {
  int directions = 0;
  for (int j = 0; j < model.unknown_count(); ++j) directions += model.derivative_order(j) + 1;
  return directions;
}

// Size of a grid correction in units of its unknowns' scales: largest component and 2-norm.
struct StepSize {
  double max = 0.0, norm = 0.0;
};

// Every value finite, in one vectorised pass (Eigen's allFinite tests element by element, a tenth
// of a warm solve): a sum of finite values is finite unless it overflows, which is divergence too.
bool AllFinite(const Eigen::MatrixXd& x) { return std::isfinite(x.sum()); }

// `inverse_scale` holds one inverted scale per entry of dz (the unknowns' repeated at every point),
// so both reductions run over contiguous arrays and vectorise.
StepSize Measure(const Eigen::MatrixXd& dz, const Eigen::ArrayXd& inverse_scale) {
  const auto scaled = Eigen::Map<const Eigen::ArrayXd>(dz.data(), dz.size()) * inverse_scale;
  return {scaled.abs().maxCoeff(), std::sqrt(scaled.square().sum())};
}

}  // namespace

//! The input and its first and second time derivatives on the grid (1 x n each).
struct PeriodicSolver::InputRates {
  InputRates(const Stencil& stencil, const PeriodicInput& input) {
    GridRates(stencil, Eigen::Map<const Eigen::RowVectorXd>(input.values.data(), input.values.size()), input.frequency,
              first, second);
  }
  Eigen::MatrixXd first, second;
};

Eigen::MatrixXd PeriodicSolver::Residual(const Eigen::MatrixXd& z, const PeriodicInput& input,
                                         std::span<const double> theta) const {
  const int n = static_cast<int>(z.cols());
  if (n == prepared_n_ && input.phases == prepared_phases_) return ResidualAt(z, input, InputRates(stencil_, input), theta);
  PeriodicSolver other(model_, options_);
  other.Prepare(input);
  return other.ResidualAt(z, input, InputRates(other.stencil_, input), theta);
}

Eigen::MatrixXd PeriodicSolver::ResidualAt(const Eigen::MatrixXd& z, const PeriodicInput& input,
                                           const InputRates& rates, std::span<const double> theta) const {
  const int m = model_.unknown_count();
  const int n = static_cast<int>(z.cols());
  Eigen::MatrixXd zd, zdd;
  GridRates(stencil_, z, input.frequency, zd, zdd);
  Eigen::MatrixXd g(m, n);
  const std::size_t values = static_cast<std::size_t>(m) * n;
  model_.Residuals<double>(std::span<const double>(z.data(), values), std::span<const double>(zd.data(), values),
                           std::span<const double>(zdd.data(), values), input.values,
                           std::span<const double>(rates.first.data(), n),
                           std::span<const double>(rates.second.data(), n), theta, std::span<double>(g.data(), values));
  g.array().colwise() *= equation_weight_.array();
  return g;
}

std::shared_ptr<const CyclicBandedLU> PeriodicSolver::Factorize(const Eigen::MatrixXd& z, const PeriodicInput& input,
                                                                const InputRates& rates, std::span<const double> theta,
                                                                int iteration, double norm) {
  if (LinearizationDirections(model_) <= kStateDirections) {
    AssembleJacobianWith<StateJet>(z, input, rates, theta);
  } else {
    AssembleJacobianWith<Jet>(z, input, rates, theta);
  }
  std::shared_ptr<CyclicBandedLU> lu;
  for (const auto& spare : lu_pool_)
    if (spare.use_count() == 1) lu = spare;
  if (!lu) {
    lu = std::make_shared<CyclicBandedLU>();
    if (lu_pool_.size() < 4) lu_pool_.push_back(lu);
  }
  if (!lu->Factorize(jacobian_))
    throw PeriodicSolverError(
        fmt::format("periodic solver: singular Jacobian at iteration {} (residual {:.3g})", iteration, norm), norm,
        iteration);
  return lu;
}

template <class J>
void PeriodicSolver::AssembleJacobianWith(const Eigen::MatrixXd& z, const PeriodicInput& input, const InputRates& rates,
                                          std::span<const double> theta) {
  const int n = static_cast<int>(z.cols());
  const double f = input.frequency;
  Eigen::MatrixXd zd, zdd;
  GridRates(stencil_, z, f, zd, zdd);
  Linearization<J> points(model_, theta, equation_weight_);
  constexpr int kBatch = Linearization<J>::kBatch;
  const int mm = model_.unknown_count() * model_.unknown_count();
  for (int start = 0; start < n; start += kBatch) {
    const int size = std::min(kBatch, n - start);
    for (int k = 0; k < size; ++k) {
      const int mu = start + k;
      points.Load(k, z.col(mu).data(), zd.col(mu).data(), zdd.col(mu).data(), input.values[mu], rates.first(0, mu),
                  rates.second(0, mu));
    }
    points.Evaluate(size);
    for (int k = 0; k < size; ++k) {
      const double* rx = points.rx.data() + k * mm;  // column-major m x m blocks of point k
      const double* rxd = points.rxd.data() + k * mm;
      const double* rxdd = points.rxdd.data() + k * mm;
      for (int offset = stencil_.kmin; offset <= stencil_.kmax; ++offset) {
        double* block = jacobian_.block(start + k, offset).data();
        const double a = stencil_.First(start + k, offset) * f;
        const double b = stencil_.Second(start + k, offset) * f * f;
        for (int e = 0; e < mm; ++e) block[e] = a * rxd[e] + b * rxdd[e];
        if (offset == 0)
          for (int e = 0; e < mm; ++e) block[e] += rx[e];
      }
    }
  }
}

namespace {

// The start-up march of MarchGuess with Jets of type J (fixed-size when the directions fit).
template <class J>
Eigen::MatrixXd March(const Model& model, const Eigen::VectorXd& equation_weight, Eigen::MatrixXd z,
                      const PeriodicInput& input, std::span<const double> theta, int periods) {
  const int n = static_cast<int>(z.cols());
  const int m = model.unknown_count();
  const double f = input.frequency;
  const Stencil march = GridStencil(Scheme::kBackward2, input);
  Eigen::MatrixXd input_first, input_second;
  GridRates(march, Eigen::Map<const Eigen::RowVectorXd>(input.values.data(), n), f, input_first, input_second);
  Linearization<J> point(model, theta, equation_weight);
  Eigen::VectorXd step_scale(m);
  for (int j = 0; j < m; ++j) step_scale[j] = model.unknown_spec(j).scale;
  std::vector<double> zd(m), zdd(m);
  Eigen::MatrixXd jacobian(m, m);  // allocated once: the march visits every point several times
  Eigen::PartialPivLU<Eigen::MatrixXd> lu(m);
  Eigen::VectorXd step(m);
  for (int pass = 0; pass < periods; ++pass)
    for (int mu = 0; mu < n; ++mu) {
      if (mu > 0) z.col(mu) = z.col(mu - 1);  // predictor: hold the previous point
      for (int iteration = 0; iteration < 20; ++iteration) {
        for (int j = 0; j < m; ++j) {
          const Rates rate = RatesAt(march, z.row(j), mu, n, f);
          zd[j] = rate.first;
          zdd[j] = rate.second;
        }
        point.Load(0, z.col(mu).data(), zd.data(), zdd.data(), input.values[mu], input_first(0, mu),
                   input_second(0, mu));
        point.Evaluate(1);
        jacobian = point.Rx(0) + march.First(mu, 0) * f * point.Rxd(0) + march.Second(mu, 0) * f * f * point.Rxdd(0);
        lu.compute(jacobian);
        step.noalias() = lu.solve(-point.r.col(0));
        if (!step.allFinite()) break;
        z.col(mu) += step;
        if ((step.array().abs() / step_scale.array()).maxCoeff() <= 1.0) break;
      }
      if (!z.col(mu).allFinite()) throw PeriodicSolverError("periodic solver: the start-up march diverged", NAN, 0);
    }
  return z;
}

}  // namespace

Eigen::MatrixXd PeriodicSolver::MarchGuess(Eigen::MatrixXd z, const PeriodicInput& input, std::span<const double> theta,
                                           int periods) const {
  // Time-march the backward scheme around the period, each point by a small Newton solve from
  // its predecessor: friction stick and slip settle locally, which a global Newton from the
  // quasi-static guess finds only after many halved steps.
  if (LinearizationDirections(model_) <= kStateDirections)
    return March<StateJet>(model_, equation_weight_, std::move(z), input, theta, periods);
  return March<Jet>(model_, equation_weight_, std::move(z), input, theta, periods);
}

Eigen::MatrixXd PeriodicSolver::QuasiStaticGuess(const PeriodicInput& input, std::span<const double> theta,
                                                 bool march_start) const {
  // Static equilibrium at every instant, each started from its neighbour's: robust for large strokes.
  const int m = model_.unknown_count();
  const int n = static_cast<int>(input.values.size());
  std::vector<int> points;
  const int wrap = 3;  // the backward2 stencil of the march reaches 3 points back
  if (march_start && n > wrap + 1) {
    for (int mu = n - wrap; mu < n; ++mu) points.push_back(mu);
    points.push_back(0);
  } else {
    for (int mu = 0; mu < n; ++mu) points.push_back(mu);
  }
  Eigen::MatrixXd z(m, n);
  std::vector<double> previous;
  for (const int mu : points) {
    previous = model_.StaticEquilibrium(input.values[mu], theta, previous);
    for (int j = 0; j < m; ++j) z(j, mu) = previous[j];
  }
  if (static_cast<int>(points.size()) < n)
    for (int mu = 1; mu < n - wrap; ++mu) z.col(mu) = z.col(0);  // the march overwrites these first
  return z;
}

Eigen::MatrixXd PeriodicSolver::ColdStart(const PeriodicInput& input, std::span<const double> theta) const {
  const int n = static_cast<int>(input.values.size());
  const int coarse_n = options_.coarse_points;
  if (coarse_n >= 8 && n >= 2 * coarse_n) {
    // Solve on the coarse grid (where the quasi-static guess and the march are cheap and Newton
    // converges in a few steps), then interpolate: the fine Newton starts close to its solution.
    PeriodicSolverOptions options = options_;
    options.scheme = Scheme::kBackward2;
    options.coarse_points = 0;
    PeriodicSolver coarse(model_, options);
    const Eigen::Map<const Eigen::RowVectorXd> values(input.values.data(), n);
    std::vector<double> coarse_phases(coarse_n);
    for (int mu = 0; mu < coarse_n; ++mu) coarse_phases[mu] = static_cast<double>(mu) / coarse_n;
    const PeriodicInput coarse_input{
        input.frequency, [&] {
          const Eigen::MatrixXd u = input.phases.empty()
                                        ? PeriodicResample(values, coarse_n)
                                        : PhaseInterpolation::Cubic(input.phases, n, coarse_phases).Rows(values);
          return std::vector<double>(u.data(), u.data() + coarse_n);
        }()};
    PeriodicSolution guess;
    guess.n = coarse_n;
    guess.frequency = input.frequency;
    guess.unknowns = coarse.MarchGuess(coarse.QuasiStaticGuess(coarse_input, theta, options_.start_up_periods > 0),
                                       coarse_input, theta, options_.start_up_periods);
    try {
      const PeriodicSolution s = coarse.Solve(coarse_input, theta, &guess);
      spdlog::trace("periodic cold start: {} Newton steps on {} points", s.newton_iterations, coarse_n);
      return input.phases.empty() ? PeriodicResample(s.unknowns, n)
                                  : PhaseInterpolation::Cubic({}, coarse_n, input.phases).Rows(s.unknowns);
    } catch (const PeriodicSolverError& e) {
      spdlog::debug("periodic cold start: no solution on {} points ({}); starting on all {}", coarse_n, e.what(), n);
    }
  }
  return MarchGuess(QuasiStaticGuess(input, theta, options_.start_up_periods > 0), input, theta,
                    options_.start_up_periods);
}

bool PeriodicSolver::TangentPrediction(const PeriodicSolution& from, std::span<const double> theta,
                                       Eigen::MatrixXd& z) const {
  // First order in the parameter change: the Newton start is then O(dtheta^2) from the solution
  // instead of O(dtheta). Only when every parameter that changed has its dz/dtheta in `from`.
  const auto& dz = from.solver_state.unknown_sensitivities;
  if (from.theta.size() != theta.size() || dz.rows() != z.size() ||
      dz.cols() != static_cast<Eigen::Index>(from.solver_state.sensitivity_parameters.size()))
    return false;
  Eigen::VectorXd change = Eigen::VectorXd::Zero(dz.cols());
  std::vector<bool> covered(theta.size(), false);
  for (std::size_t k = 0; k < from.solver_state.sensitivity_parameters.size(); ++k) {
    const int i = from.solver_state.sensitivity_parameters[k];
    covered[i] = true;
    change[static_cast<Eigen::Index>(k)] = theta[i] - from.theta[i];
  }
  for (std::size_t i = 0; i < theta.size(); ++i)
    if (!covered[i] && theta[i] != from.theta[i]) return false;
  if (change.isZero()) return false;
  Eigen::MatrixXd predicted = z;
  Eigen::Map<Eigen::VectorXd>(predicted.data(), predicted.size()) += dz * change;
  if (!AllFinite(predicted)) return false;
  z = std::move(predicted);
  return true;
}

PeriodicSolution PeriodicSolver::Solve(const PeriodicInput& input, std::span<const double> theta,
                                       const PeriodicSolution* warm_start) {
  const int n = static_cast<int>(input.values.size());
  const int m = model_.unknown_count();
  if (!(input.frequency > 0)) throw std::invalid_argument("periodic solver: the input frequency must be positive");
  if (static_cast<int>(theta.size()) != model_.parameter_count())
    throw std::invalid_argument(fmt::format("periodic solver: {} parameter values for a model with {}", theta.size(),
                                            model_.parameter_count()));
  for (double v : input.values)
    if (!std::isfinite(v)) throw std::invalid_argument("periodic solver: the input has non-finite values");
  Prepare(input);
  const InputRates rates(stencil_, input);

  if (warm_start && warm_start->n == n && warm_start->unknowns.rows() == m && warm_start->unknowns.cols() == n) {
    std::shared_ptr<const CyclicBandedLU> lu;
    const PeriodicSolverState& carried = warm_start->solver_state;
    if (options_.reuse_contraction > 0 && carried.jacobian && carried.jacobian->rows() == n * m) lu = carried.jacobian;
    Eigen::MatrixXd predicted = warm_start->unknowns;
    if (TangentPrediction(*warm_start, theta, predicted)) {
      try {
        return Newton(std::move(predicted), lu, input, rates, theta);
      } catch (const PeriodicSolverError& e) {  // a long step: the tangent overshot the model's range
        spdlog::debug("periodic solver: no solution from the tangent prediction ({}); from the warm start itself",
                      e.what());
      }
    }
    return Newton(warm_start->unknowns, lu, input, rates, theta);
  }
  Eigen::MatrixXd z;
  try {
    z = ColdStart(input, theta);
  } catch (const ModelError& e) {
    throw PeriodicSolverError(fmt::format("periodic solver: no static-equilibrium guess: {}", e.what()), NAN, 0);
  }
  return Newton(std::move(z), nullptr, input, rates, theta);
}

PeriodicSolution PeriodicSolver::Newton(Eigen::MatrixXd z, std::shared_ptr<const CyclicBandedLU> lu,
                                        const PeriodicInput& input, const InputRates& rates,
                                        std::span<const double> theta) {
  const int n = static_cast<int>(input.values.size());
  const int m = model_.unknown_count();
  Eigen::ArrayXd inverse_scale(static_cast<Eigen::Index>(m) * n);  // Newton's tolerance per unknown, inverted
  for (int j = 0; j < m; ++j)
    inverse_scale(Eigen::seqN(j, n, m)) = 1.0 / (model_.unknown_spec(j).scale * options_.tolerance);

  Eigen::MatrixXd g = ResidualAt(z, input, rates, theta);
  double norm = g.norm();  // not finite when any value is not
  int iteration = 0, factorizations = 0;
  bool converged = false, fresh = false;
  double last_contraction = INFINITY;  // of the last step with the factorisation in use
  Eigen::MatrixXd step;  // the next Newton direction when the last step left one (simplified Newton)
  for (; iteration < options_.max_iterations && !converged; ++iteration) {
    if (!std::isfinite(norm))
      throw PeriodicSolverError(
          fmt::format("periodic solver: non-finite residual at iteration {} (the guess is outside the model's range)",
                      iteration),
          norm, iteration);
    fresh = !lu;
    if (fresh) {
      lu = Factorize(z, input, rates, theta, iteration, norm);
      ++factorizations;
      last_contraction = INFINITY;
      step.resize(0, 0);
    }
    if (step.size() == 0) {
      step = -g;
      lu->Solve(Eigen::Map<Eigen::VectorXd>(step.data(), step.size()));
    }
    const StepSize step_size = Measure(step, inverse_scale);
    converged = step_size.max <= 1.0;
    // Step halving (Fey) with Deuflhard's natural monotonicity test: accept the first fraction
    // whose simplified Newton correction J^-1 G(trial) (same factorisation, scaled by the unknowns'
    // scales) shrinks. Unlike the residual norm this test does not depend on how the equations are
    // scaled, and it lets Newton cross the friction switches of force-driven problems in few steps.
    // A factorisation carried over from earlier iterates is not halved with: it is replaced.
    const double step_norm = step_size.norm;
    const int halvings = fresh ? options_.max_halvings : 0;
    double lambda = 1.0;
    bool accepted = false;
    Eigen::MatrixXd correction;
    double contraction = INFINITY;
    for (int halving = 0; halving <= halvings; ++halving, lambda *= 0.5) {
      Eigen::MatrixXd trial = z + lambda * step;
      Eigen::MatrixXd g_trial = ResidualAt(trial, input, rates, theta);
      const double trial_norm = g_trial.norm();
      bool descent = converged;
      if (!descent && std::isfinite(trial_norm)) {
        correction = -g_trial;
        lu->Solve(Eigen::Map<Eigen::VectorXd>(correction.data(), correction.size()));
        const StepSize correction_size = Measure(correction, inverse_scale);
        contraction = correction_size.norm / step_norm;
        descent = contraction <= 1.0 - 0.25 * lambda;
        // After a full step the simplified correction is the next simplified Newton step; it is
        // applied and Newton stops when the error left after it is below the tolerance. After a
        // step with a new Jacobian that is when the correction itself is (what remains is a
        // fraction of it). After a simplified step, the ratio of consecutive corrections is the
        // chord's contraction Theta and the error left about Theta / (1 - Theta) times the
        // correction (Deuflhard); the largest components (near friction switches) may contract
        // slower than the norm, so Theta is the larger of the two ratios.
        const double theta_max = std::max(contraction, correction_size.max / step_size.max);
        if (lambda == 1.0) last_contraction = theta_max;
        const double error_left = fresh ? correction_size.max
                                        : (theta_max < 0.5 ? theta_max / (1.0 - theta_max) * correction_size.max : INFINITY);
        if (descent && lambda == 1.0 && error_left <= 1.0) {
          converged = true;
          trial += correction;
        }
      }
      if (descent) {
        z = std::move(trial);
        g = std::move(g_trial);
        norm = trial_norm;
        accepted = true;
        break;
      }
    }
    if (!accepted && !fresh) {  // the carried factorisation does not fit here: assemble a new one
      last_contraction = INFINITY;
      lu.reset();
      step.resize(0, 0);
      converged = false;
      continue;
    }
    if (!accepted)
      throw PeriodicSolverError(
          fmt::format("periodic solver: no descent after {} step halvings at iteration {}; scaled residual {:.3g} "
                      "(no periodic solution near the guess)",
                      options_.max_halvings, iteration, norm),
          norm, iteration);
    spdlog::trace("periodic Newton {}: residual {:.3e} step {}{}", iteration, norm, lambda, fresh ? "" : " (simplified)");
    if (converged) break;
    // Simplified Newton: while a full step's correction contracts fast, it is the next step.
    if (lambda == 1.0 && correction.size() > 0 && contraction <= options_.reuse_contraction) {
      step = std::move(correction);
    } else {
      lu.reset();
      step.resize(0, 0);
    }
  }
  if (converged) ++iteration;  // the loop left before counting the converged step
  if (!converged || !std::isfinite(norm))
    throw PeriodicSolverError(fmt::format("periodic solver: not converged after {} iterations; scaled residual {:.3g}",
                                          iteration, norm),
                              norm, iteration);

  SolverCounts counts{iteration, factorizations, g.lpNorm<Eigen::Infinity>(), norm};
  PeriodicSolverState state{std::move(lu), fresh ? 0.0 : last_contraction, {}, {}};
  return Solution(std::move(z), input, theta, counts, std::move(state));
}

PeriodicSolution PeriodicSolver::Solution(Eigen::MatrixXd z, const PeriodicInput& input, std::span<const double> theta,
                                          const SolverCounts& counts, PeriodicSolverState state) const {
  const int n = static_cast<int>(input.values.size());
  const int m = model_.unknown_count();
  PeriodicSolution solution;
  solution.scheme = options_.scheme;
  solution.frequency = input.frequency;
  solution.n = n;
  solution.unknowns = std::move(z);
  solution.input = input;
  solution.theta.assign(theta.begin(), theta.end());
  solution.newton_iterations = counts.iterations;
  solution.factorizations = counts.factorizations;
  solution.residual_norm = counts.residual_norm;
  solution.solver_state = std::move(state);
  solution.channels = model_.output_channels();
  solution.outputs.resize(static_cast<int>(solution.channels.size()), n);
  const std::size_t channels = solution.channels.size();
  for (int mu = 0; mu < n; ++mu)  // column mu of the outputs is contiguous: written in place
    model_.Outputs<double>(std::span<const double>(solution.unknowns.col(mu).data(), m), input.values[mu], theta,
                           std::span<double>(solution.outputs.col(mu).data(), channels));
  if (!AllFinite(solution.outputs))
    throw PeriodicSolverError("periodic solver: non-finite outputs at the solution", counts.norm, counts.iterations);
  return solution;
}

namespace {

// Jets for parameter sensitivities: constants, and the parameters `wanted` as directions 0, 1, ...
template <class J>
struct ParameterJets {
  ParameterJets(std::span<const double> theta, const std::vector<int>& wanted)
      : directions(J::DerType::RowsAtCompileTime == Eigen::Dynamic ? static_cast<int>(wanted.size())
                                                                   : int(J::DerType::RowsAtCompileTime)) {
    for (double t : theta) theta_jet.push_back(Constant(t));
    for (std::size_t k = 0; k < wanted.size(); ++k)
      theta_jet[wanted[k]] = J(theta[wanted[k]], J::DerType::Unit(directions, static_cast<int>(k)));
  }
  J Constant(double v) const { return J(v, J::DerType::Zero(directions)); }
  int directions;
  std::vector<J> theta_jet;
};

// The residual Jets of every grid point, a batch of points at a time (one call per term and batch,
// as the Jacobian's): the unknowns and their rates as constants, the input and its rate and
// acceleration as directions 0, 1, 2 when `input_directions` (else constants), the parameters as
// `jets` has them. `use(start, size, r)` reads the residuals of the points start .. start + size - 1.
template <class J, class Use>
void ResidualJetBatches(const Model& model, const Eigen::MatrixXd& z, const Eigen::MatrixXd& zd,
                        const Eigen::MatrixXd& zdd, const PeriodicInput& input, const Eigen::MatrixXd& input_first,
                        const Eigen::MatrixXd& input_second, const ParameterJets<J>& jets, bool input_directions,
                        const Use& use) {
  constexpr int kBatch = 32;
  const int m = model.unknown_count(), n = static_cast<int>(z.cols());
  std::vector<J> x(kBatch * m, jets.Constant(0.0)), xd(x), xdd(x), r(x), u(kBatch, jets.Constant(0.0)), ud(u), udd(u);
  if (input_directions)
    for (int k = 0; k < kBatch; ++k) {
      u[k] = J(0.0, J::DerType::Unit(jets.directions, 0));
      ud[k] = J(0.0, J::DerType::Unit(jets.directions, 1));
      udd[k] = J(0.0, J::DerType::Unit(jets.directions, 2));
    }
  for (int start = 0; start < n; start += kBatch) {  // the directions stay; each point loads values
    const int size = std::min(kBatch, n - start);
    for (int k = 0; k < size; ++k) {
      const int mu = start + k;
      for (int j = 0; j < m; ++j) {
        x[k * m + j].value() = z(j, mu);
        xd[k * m + j].value() = zd(j, mu);
        xdd[k * m + j].value() = zdd(j, mu);
      }
      u[k].value() = input.values[mu];
      ud[k].value() = input_first(0, mu);
      udd[k].value() = input_second(0, mu);
    }
    const std::size_t values = static_cast<std::size_t>(size) * m;
    model.Residuals<J>(std::span<const J>(x.data(), values), std::span<const J>(xd.data(), values),
                       std::span<const J>(xdd.data(), values), std::span<const J>(u.data(), size),
                       std::span<const J>(ud.data(), size), std::span<const J>(udd.data(), size), jets.theta_jet,
                       std::span<J>(r.data(), values));
    use(start, size, r);
  }
}

}  // namespace

template <class J>
void PeriodicSolver::ParameterResiduals(const PeriodicSolution& solution, const InputRates& rates,
                                        std::span<const double> theta, const std::vector<int>& wanted,
                                        Eigen::Ref<Eigen::MatrixXd> rhs) const {
  const int m = model_.unknown_count(), nd = static_cast<int>(wanted.size());
  const ParameterJets<J> jets(theta, wanted);
  const auto& z = solution.unknowns;
  const PeriodicInput& input = solution.input;
  Eigen::MatrixXd zd, zdd;
  GridRates(stencil_, z, input.frequency, zd, zdd);
  ResidualJetBatches(model_, z, zd, zdd, input, rates.first, rates.second, jets, false,
                     [&](int start, int size, const std::vector<J>& r) {
                       for (int k = 0; k < size; ++k)
                         for (int i = 0; i < m; ++i) {
                           const auto& d = r[k * m + i].derivatives();
                           for (int p = 0; p < nd; ++p)
                             rhs((start + k) * m + i, p) = d.size() >= nd ? -d[p] * equation_weight_[i] : 0.0;
                         }
                     });
}

template <class J>
void PeriodicSolver::OutputDerivatives(const PeriodicSolution& solution, std::span<const double> theta,
                                       const std::vector<int>& wanted, const Eigen::Ref<const Eigen::MatrixXd>& dz,
                                       std::vector<Eigen::MatrixXd>& sens, int first_column) const {
  const int m = model_.unknown_count(), n = solution.n, nd = static_cast<int>(wanted.size());
  const ParameterJets<J> jets(theta, wanted);
  const auto& z = solution.unknowns;
  std::vector<J> x(m), y(solution.channels.size());
  for (int mu = 0; mu < n; ++mu) {
    for (int j = 0; j < m; ++j) {
      typename J::DerType d = J::DerType::Zero(jets.directions);
      d.head(nd) = dz.row(mu * m + j).transpose();
      x[j] = J(z(j, mu), d);
    }
    model_.Outputs<J>(x, jets.Constant(solution.input.values[mu]), jets.theta_jet, y);
    for (std::size_t c = 0; c < y.size(); ++c)
      for (int k = 0; k < nd; ++k) sens[c](mu, first_column + k) = y[c].derivatives()[k];
  }
}

void PeriodicSolver::MakeJacobianCurrent(const PeriodicSolution& solution, const InputRates& rates,
                                         std::span<const double> theta) {
  PeriodicSolverState& state = solution.solver_state;
  if (state.jacobian && state.jacobian_contraction == 0.0 && state.jacobian->rows() == solution.unknowns.size())
    return;
  // Simplified Newton steps (or a guess) led here: eq. 14 wants the Jacobian at the solution.
  state.jacobian = Factorize(solution.unknowns, solution.input, rates, theta, 0, 0.0);
  state.jacobian_contraction = 0.0;
}

Eigen::MatrixXd PeriodicSolver::InputGradients(const PeriodicSolution& solution, std::span<const double> theta,
                                               const std::vector<Eigen::MatrixXd>& output_weights) {
  const int m = model_.unknown_count(), n = solution.n;
  const int channels = static_cast<int>(solution.channels.size());
  if (solution.unknowns.rows() != m || solution.unknowns.cols() != n ||
      static_cast<int>(theta.size()) != model_.parameter_count())
    throw std::invalid_argument("periodic solver: input gradients need a solution of this model");
  if (static_cast<int>(output_weights.size()) != channels)
    throw std::invalid_argument(fmt::format("periodic solver: input gradients need weights for all {} outputs", channels));
  const Eigen::Index columns = output_weights.empty() ? 0 : output_weights[0].cols();
  for (const auto& w : output_weights)
    if (w.rows() != n || w.cols() != columns)
      throw std::invalid_argument("periodic solver: output weights must be n x k, the same k for every output");
  if (m + 1 > kStateDirections) throw std::invalid_argument("periodic solver: too many unknowns for input gradients");
  const PeriodicInput& input = solution.input;
  Prepare(input);
  const InputRates rates(stencil_, input);
  MakeJacobianCurrent(solution, rates, theta);
  using J = StateJet;
  static_assert(kStateDirections >= 3);
  const ParameterJets<J> jets(theta, {});  // parameters constant here
  const auto& z = solution.unknowns;
  Eigen::MatrixXd zd, zdd;
  GridRates(stencil_, z, input.frequency, zd, zdd);

  // With y = Y_x dz + Y_u du and G_z dz = -G_u du (G_u: the residual's derivatives in the input,
  // its rate and acceleration, the rates by the scheme's stencil D1, D2):
  // d(w^T y)/du = Y_u^T w - G_u^T lambda with G_z^T lambda = Y_x^T w (one adjoint solve per column).
  Eigen::MatrixXd gradient = Eigen::MatrixXd::Zero(n, columns);
  Eigen::MatrixXd lambda(static_cast<Eigen::Index>(m) * n, columns);
  {
    std::vector<J> x(m), y(channels);
    for (int mu = 0; mu < n; ++mu) {
      for (int j = 0; j < m; ++j) x[j] = J(z(j, mu), J::DerType::Unit(j));
      model_.Outputs<J>(x, J(input.values[mu], J::DerType::Unit(m)), jets.theta_jet, y);
      for (Eigen::Index b = 0; b < columns; ++b) {
        double du = 0.0;
        for (int j = 0; j < m; ++j) lambda(mu * m + j, b) = 0.0;
        for (int c = 0; c < channels; ++c) {
          const double w = output_weights[c](mu, b);
          const auto& d = y[c].derivatives();
          for (int j = 0; j < m; ++j) lambda(mu * m + j, b) += w * d[j];
          du += w * d[m];
        }
        gradient(mu, b) = du;
      }
    }
  }
  solution.solver_state.jacobian->SolveTransposed(lambda);
  // G_u^T lambda: per point the input, rate and acceleration parts, the rate parts through D^T.
  Eigen::MatrixXd a0(columns, n), a1(columns, n), a2(columns, n);
  ResidualJetBatches(model_, z, zd, zdd, input, rates.first, rates.second, jets, true,
                     [&](int start, int size, const std::vector<J>& r) {
                       for (int k = 0; k < size; ++k) {
                         const int mu = start + k;
                         for (Eigen::Index b = 0; b < columns; ++b) {
                           double v0 = 0.0, v1 = 0.0, v2 = 0.0;
                           for (int i = 0; i < m; ++i) {
                             const double l = lambda(mu * m + i, b) * equation_weight_[i];
                             const auto& d = r[k * m + i].derivatives();
                             v0 += l * d[0];
                             v1 += l * d[1];
                             v2 += l * d[2];
                           }
                           a0(b, mu) = v0;
                           a1(b, mu) = v1;
                           a2(b, mu) = v2;
                         }
                       }
                     });
  // (D1^T a1)(nu) = f sum_k first[k] a1(nu - k): the stencil read backwards.
  const double f = input.frequency;
  for (int k = stencil_.kmin; k <= stencil_.kmax; ++k)
    for (int mu = 0; mu < n; ++mu) {
      const double c1 = stencil_.First(mu, k) * f, c2 = stencil_.Second(mu, k) * f * f;
      if (c1 == 0.0 && c2 == 0.0) continue;
      const int nu = ((mu + k) % n + n) % n;  // row mu reads the input at nu
      a0.col(nu) += c1 * a1.col(mu) + c2 * a2.col(mu);
    }
  gradient -= a0.transpose();
  return gradient;
}

std::vector<Eigen::MatrixXd> PeriodicSolver::InputSensitivities(const PeriodicSolution& solution,
                                                                std::span<const double> theta,
                                                                const Eigen::MatrixXd& directions, bool exact) {
  const int m = model_.unknown_count(), n = solution.n;
  const int channels = static_cast<int>(solution.channels.size());
  if (solution.unknowns.rows() != m || solution.unknowns.cols() != n ||
      static_cast<int>(theta.size()) != model_.parameter_count())
    throw std::invalid_argument("periodic solver: input sensitivities need a solution of this model");
  if (directions.rows() != n) throw std::invalid_argument("periodic solver: input directions must be n x k");
  if (m + 1 > kStateDirections) throw std::invalid_argument("periodic solver: too many unknowns for input sensitivities");
  const Eigen::Index columns = directions.cols();
  const PeriodicInput& input = solution.input;
  Prepare(input);
  const InputRates rates(stencil_, input);
  const PeriodicSolverState& state = solution.solver_state;
  const bool close_enough = !exact && state.jacobian && state.jacobian->rows() == solution.unknowns.size() &&
                            state.jacobian_contraction <= 0.05;
  if (!close_enough) MakeJacobianCurrent(solution, rates, theta);
  using J = StateJet;
  static_assert(kStateDirections >= 3);
  const ParameterJets<J> jets(theta, {});  // parameters constant here
  const auto& z = solution.unknowns;
  Eigen::MatrixXd zd, zdd;
  GridRates(stencil_, z, input.frequency, zd, zdd);
  // The directions' rates as the solver takes the input's (n x k like the directions: whole shifted
  // blocks of rows per stencil offset), kept for the next call with the same directions.
  const double f = input.frequency;
  if (rated_directions_.rows() != n || rated_directions_.cols() != columns || direction_frequency_ != f ||
      rated_directions_ != directions) {
    direction_first_.setZero(n, columns);
    direction_second_.setZero(n, columns);
    Eigen::VectorXd c1(n), c2(n);  // the offset's weight at every point
    for (int k = stencil_.kmin; k <= stencil_.kmax; ++k) {
      for (int mu = 0; mu < n; ++mu) {
        c1[mu] = stencil_.First(mu, k) * f;
        c2[mu] = stencil_.Second(mu, k) * f * f;
      }
      if (c1.isZero(0.0) && c2.isZero(0.0)) continue;
      const int shift = ((k % n) + n) % n;  // row mu reads row (mu + shift) mod n
      direction_first_.topRows(n - shift) += c1.head(n - shift).asDiagonal() * directions.middleRows(shift, n - shift);
      direction_second_.topRows(n - shift) += c2.head(n - shift).asDiagonal() * directions.middleRows(shift, n - shift);
      if (shift > 0) {
        direction_first_.bottomRows(shift) += c1.tail(shift).asDiagonal() * directions.topRows(shift);
        direction_second_.bottomRows(shift) += c2.tail(shift).asDiagonal() * directions.topRows(shift);
      }
    }
    rated_directions_ = directions;
    direction_frequency_ = f;
  }
  const Eigen::MatrixXd& d1 = direction_first_;
  const Eigen::MatrixXd& d2 = direction_second_;
  // -(G_u0, G_u1, G_u2) per equation (a row each) and point, scaled like G.
  Eigen::MatrixXd g0(n, m), g1(n, m), g2(n, m);
  ResidualJetBatches(model_, z, zd, zdd, input, rates.first, rates.second, jets, true,
                     [&](int start, int size, const std::vector<J>& r) {
                       for (int k = 0; k < size; ++k)
                         for (int i = 0; i < m; ++i) {
                           const auto& d = r[k * m + i].derivatives();
                           const double w = -equation_weight_[i];
                           g0(start + k, i) = w * d[0];
                           g1(start + k, i) = w * d[1];
                           g2(start + k, i) = w * d[2];
                         }
                     });
  // The rows of one unknown (or equation) i of every point in an (m n x k) matrix: every m-th row.
  using Rows = Eigen::Map<Eigen::MatrixXd, 0, Eigen::Stride<Eigen::Dynamic, Eigen::Dynamic>>;
  const auto unknown_rows = [&](Eigen::MatrixXd& x, int i) {
    return Rows(x.data() + i, n, x.cols(), Eigen::Stride<Eigen::Dynamic, Eigen::Dynamic>(x.outerStride(), m));
  };
  // G_z dz = -(G_u0 phi + G_u1 D1 phi + G_u2 D2 phi), equation by equation over all points and directions.
  Eigen::MatrixXd dz(static_cast<Eigen::Index>(m) * n, columns);
  for (int i = 0; i < m; ++i)
    unknown_rows(dz, i) = g0.col(i).asDiagonal() * directions + g1.col(i).asDiagonal() * d1 + g2.col(i).asDiagonal() * d2;
  solution.solver_state.jacobian->Solve(dz);
  // dy = Y_z dz + Y_u phi: the output derivatives per point once, then unknown by unknown.
  std::vector<Eigen::MatrixXd> derivative(channels, Eigen::MatrixXd(n, m + 1));  // per channel: unknowns, input
  {
    std::vector<J> x(m), y(channels);
    for (int mu = 0; mu < n; ++mu) {
      for (int j = 0; j < m; ++j) x[j] = J(z(j, mu), J::DerType::Unit(j));
      model_.Outputs<J>(x, J(input.values[mu], J::DerType::Unit(m)), jets.theta_jet, y);
      for (int c = 0; c < channels; ++c) derivative[c].row(mu) = y[c].derivatives().head(m + 1).transpose();
    }
  }
  std::vector<Eigen::MatrixXd> sens(channels);
  for (int c = 0; c < channels; ++c) {
    sens[c].noalias() = derivative[c].col(m).asDiagonal() * directions;
    for (int j = 0; j < m; ++j)
      if (!derivative[c].col(j).isZero(0.0)) sens[c].noalias() += derivative[c].col(j).asDiagonal() * unknown_rows(dz, j);
  }
  return sens;
}

std::vector<Eigen::MatrixXd> PeriodicSolver::OutputSensitivities(const PeriodicSolution& solution,
                                                                 std::span<const double> theta,
                                                                 std::span<const int> parameters, bool exact) {
  const int m = model_.unknown_count();
  const int n = solution.n;
  const int np = model_.parameter_count();
  if (solution.unknowns.rows() != m || solution.unknowns.cols() != n || static_cast<int>(theta.size()) != np)
    throw std::invalid_argument("periodic solver: sensitivities of a solution of another model or grid");
  std::vector<int> wanted(parameters.begin(), parameters.end());
  if (wanted.empty())
    for (int i = 0; i < np; ++i) wanted.push_back(i);
  for (int i : wanted)
    if (i < 0 || i >= np) throw std::invalid_argument(fmt::format("periodic solver: no parameter at position {}", i));
  const int nd = static_cast<int>(wanted.size());
  Prepare(solution.input);
  const InputRates rates(stencil_, solution.input);
  const PeriodicSolverState& state = solution.solver_state;
  const bool close_enough = !exact && state.jacobian && state.jacobian->rows() == solution.unknowns.size() &&
                            state.jacobian_contraction <= 0.05;
  if (!close_enough) MakeJacobianCurrent(solution, rates, theta);
  // d(outputs)/dtheta = df/dz dz/dtheta + df/dtheta (eq. 15), with dz/dtheta from eq. 14. The
  // parameters go through fixed-size Jets, kStateDirections at a time: their unrolled arithmetic over
  // batches of points costs a third of runtime-size Jets point by point, even with the residual's
  // values evaluated once per chunk (13 parameters of the wide 2 dof fit: 2 chunks).
  const auto chunk = [&](int first) {
    return std::vector<int>(wanted.begin() + first, wanted.begin() + std::min(nd, first + kStateDirections));
  };
  Eigen::MatrixXd dz(static_cast<Eigen::Index>(m) * n, nd);
  for (int first = 0; first < nd; first += kStateDirections) {
    const std::vector<int> part = chunk(first);
    ParameterResiduals<StateJet>(solution, rates, theta, part, dz.middleCols(first, static_cast<Eigen::Index>(part.size())));
  }
  solution.solver_state.jacobian->Solve(dz);  // -dG/dtheta became dz/dtheta (eq. 14)
  std::vector<Eigen::MatrixXd> sens(solution.channels.size(), Eigen::MatrixXd(n, nd));
  for (int first = 0; first < nd; first += kStateDirections) {
    const std::vector<int> part = chunk(first);
    OutputDerivatives<StateJet>(solution, theta, part, dz.middleCols(first, static_cast<Eigen::Index>(part.size())), sens,
                                first);
  }
  solution.solver_state.unknown_sensitivities = std::move(dz);
  solution.solver_state.sensitivity_parameters = wanted;
  return sens;
}

}  // namespace strut::ident
