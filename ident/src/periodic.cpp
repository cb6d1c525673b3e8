#include "strut/ident/periodic.h"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <numbers>
#include <spdlog/spdlog.h>

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

PeriodicInput PeriodicInput::Sine(double frequency, double mean, double amplitude, int n) {
  PeriodicInput in;
  in.frequency = frequency;
  in.values.resize(n);
  for (int mu = 0; mu < n; ++mu) in.values[mu] = mean + amplitude * std::sin(2.0 * std::numbers::pi * mu / n);
  return in;
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
  return true;
}

std::vector<double> PeriodicSolution::time() const {
  std::vector<double> t(n);
  for (int mu = 0; mu < n; ++mu) t[mu] = mu / (n * frequency);
  return t;
}

Eigen::VectorXd PeriodicSolution::channel(std::string_view name) const {
  for (std::size_t c = 0; c < channels.size(); ++c)
    if (channels[c] == name) return outputs.row(static_cast<int>(c)).transpose();
  throw std::out_of_range(fmt::format("periodic solution has no channel '{}'", name));
}

PeriodicSolver::PeriodicSolver(Model model, PeriodicSolverOptions options)
    : model_(std::move(model)), options_(options) {
  std::string error;
  if (!options_.IsValid(&error)) throw std::invalid_argument("periodic solver options: " + error);
}

void PeriodicSolver::Prepare(int n) {
  if (n == prepared_n_) return;
  const int minimum = options_.scheme == Scheme::kSpectral ? 4 : 8;
  if (n < minimum) throw std::invalid_argument(fmt::format("periodic solver needs n >= {}, got {}", minimum, n));
  stencil_ = Stencil::For(options_.scheme, n);
  jacobian_ = CyclicBlockBanded(n, model_.unknown_count(), stencil_.kmin, stencil_.kmax);
  prepared_n_ = n;
  lu_valid_ = false;
}

namespace {

// Time derivatives (real time) of a periodic grid function at point mu.
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
    d1 += s.first[k - s.kmin] * v;
    d2 += s.second[k - s.kmin] * v;
  }
  return {d1 * frequency, d2 * frequency * frequency};
}

std::vector<Rates> InputRates(const Stencil& s, const PeriodicInput& input) {
  const int n = static_cast<int>(input.values.size());
  const Eigen::Map<const Eigen::VectorXd> u(input.values.data(), n);
  std::vector<Rates> rates(n);
  for (int mu = 0; mu < n; ++mu) rates[mu] = RatesAt(s, u, mu, n, input.frequency);
  return rates;
}

// Residual of one grid point and its derivatives with respect to the unknowns and their rates,
// scaled like G: r, dr/dx, dr/dx', dr/dx''. J is the Jet type that carries the directions.
template <class J>
struct PointLinearization {
  PointLinearization(const Model& model, std::span<const double> theta) : model(model) {
    const int m = model.unknown_count();
    first_direction.assign(m + 1, 0);
    for (int j = 0; j < m; ++j) first_direction[j + 1] = first_direction[j] + model.derivative_order(j) + 1;
    using Derivatives = typename J::DerType;
    directions = Derivatives::RowsAtCompileTime == Eigen::Dynamic ? first_direction[m]
                                                                 : int(Derivatives::RowsAtCompileTime);
    for (double t : theta) theta_jet.push_back(Constant(t));
    x.resize(m);
    xd.resize(m);
    xdd.resize(m);
    residual.resize(m);
    r.resize(m);
    rx.resize(m, m);
    rxd.resize(m, m);
    rxdd.resize(m, m);
  }
  // All Jets carry every direction (see autodiff.h).
  J Constant(double v) const { return J(v, J::DerType::Zero(directions)); }

  void Evaluate(const Stencil& stencil, const Eigen::MatrixXd& z, int mu, double f, double u, double ud, double udd) {
    using Derivatives = typename J::DerType;
    const int m = model.unknown_count();
    const int n = static_cast<int>(z.cols());
    for (int j = 0; j < m; ++j) {
      const Rates rate = RatesAt(stencil, z.row(j), mu, n, f);
      const int order = model.derivative_order(j), d0 = first_direction[j];
      x[j] = J(z(j, mu), Derivatives::Unit(directions, d0));
      xd[j] = order >= 1 ? J(rate.first, Derivatives::Unit(directions, d0 + 1)) : Constant(rate.first);
      xdd[j] = order >= 2 ? J(rate.second, Derivatives::Unit(directions, d0 + 2)) : Constant(rate.second);
    }
    model.Residual<J>(x, xd, xdd, Constant(u), Constant(ud), Constant(udd), theta_jet, residual);
    for (int i = 0; i < m; ++i) {
      const double scale = 1.0 / model.equation_scale(i);
      const auto& d = residual[i].derivatives();
      r[i] = residual[i].value() * scale;
      for (int j = 0; j < m; ++j) {
        const int order = model.derivative_order(j), d0 = first_direction[j];
        rx(i, j) = d[d0] * scale;
        rxd(i, j) = order >= 1 ? d[d0 + 1] * scale : 0.0;
        rxdd(i, j) = order >= 2 ? d[d0 + 2] * scale : 0.0;
      }
    }
  }

  const Model& model;
  std::vector<int> first_direction;
  int directions = 0;
  std::vector<J> theta_jet, x, xd, xdd, residual;
  Eigen::VectorXd r;
  Eigen::MatrixXd rx, rxd, rxdd;
};

}  // namespace

Eigen::MatrixXd PeriodicSolver::Residual(const Eigen::MatrixXd& z, const PeriodicInput& input,
                                         std::span<const double> theta) const {
  const int m = model_.unknown_count();
  const int n = static_cast<int>(z.cols());
  const Stencil stencil = n == prepared_n_ ? stencil_ : Stencil::For(options_.scheme, n);
  const auto input_rates = InputRates(stencil, input);
  Eigen::MatrixXd g(m, n);
  std::vector<double> xd(m), xdd(m), r(m);
  for (int mu = 0; mu < n; ++mu) {
    for (int j = 0; j < m; ++j) {
      const Rates rate = RatesAt(stencil, z.row(j), mu, n, input.frequency);
      xd[j] = rate.first;
      xdd[j] = rate.second;
    }
    model_.Residual<double>(std::span<const double>(z.col(mu).data(), m), xd, xdd, input.values[mu],
                            input_rates[mu].first, input_rates[mu].second, theta, r);
    for (int j = 0; j < m; ++j) g(j, mu) = r[j] / model_.equation_scale(j);
  }
  return g;
}

void PeriodicSolver::AssembleJacobian(const Eigen::MatrixXd& z, const PeriodicInput& input,
                                      std::span<const double> theta) {
  const int m = model_.unknown_count();
  int directions = 0;
  for (int j = 0; j < m; ++j) directions += model_.derivative_order(j) + 1;
  if (directions <= kStateDirections) {
    AssembleJacobianWith<StateJet>(z, input, theta);
  } else {
    AssembleJacobianWith<Jet>(z, input, theta);
  }
}

template <class J>
void PeriodicSolver::AssembleJacobianWith(const Eigen::MatrixXd& z, const PeriodicInput& input,
                                          std::span<const double> theta) {
  const int n = static_cast<int>(z.cols());
  const double f = input.frequency;
  const auto input_rates = InputRates(stencil_, input);
  PointLinearization<J> point(model_, theta);
  for (int mu = 0; mu < n; ++mu) {
    point.Evaluate(stencil_, z, mu, f, input.values[mu], input_rates[mu].first, input_rates[mu].second);
    for (int k = stencil_.kmin; k <= stencil_.kmax; ++k) {
      auto block = jacobian_.block(mu, k);
      const double a = stencil_.first[k - stencil_.kmin] * f;
      const double b = stencil_.second[k - stencil_.kmin] * f * f;
      block = a * point.rxd + b * point.rxdd;
      if (k == 0) block += point.rx;
    }
  }
}

Eigen::MatrixXd PeriodicSolver::MarchGuess(Eigen::MatrixXd z, const PeriodicInput& input, std::span<const double> theta,
                                           int periods) const {
  // Time-march the backward scheme around the period, each point by a small Newton solve from
  // its predecessor: friction stick and slip settle locally, which a global Newton from the
  // quasi-static guess finds only after many halved steps.
  const int n = static_cast<int>(z.cols());
  const int m = model_.unknown_count();
  const double f = input.frequency;
  const Stencil march = Stencil::For(Scheme::kBackward2, n);
  const auto input_rates = InputRates(march, input);
  PointLinearization<Jet> point(model_, theta);
  const double a0 = march.first[-march.kmin] * f, b0 = march.second[-march.kmin] * f * f;
  Eigen::VectorXd step_scale(m);
  for (int j = 0; j < m; ++j) step_scale[j] = model_.unknown_spec(j).scale;
  for (int pass = 0; pass < periods; ++pass)
    for (int mu = 0; mu < n; ++mu) {
      if (mu > 0) z.col(mu) = z.col(mu - 1);  // predictor: hold the previous point
      for (int iteration = 0; iteration < 20; ++iteration) {
        point.Evaluate(march, z, mu, f, input.values[mu], input_rates[mu].first, input_rates[mu].second);
        const Eigen::MatrixXd jac = point.rx + a0 * point.rxd + b0 * point.rxdd;
        const Eigen::VectorXd step = jac.partialPivLu().solve(-point.r);
        if (!step.allFinite()) break;
        z.col(mu) += step;
        if ((step.array().abs() / step_scale.array()).maxCoeff() <= 1.0) break;
      }
      if (!z.col(mu).allFinite()) throw PeriodicSolverError("periodic solver: the start-up march diverged", NAN, 0);
    }
  return z;
}

Eigen::MatrixXd PeriodicSolver::QuasiStaticGuess(const PeriodicInput& input, std::span<const double> theta) const {
  // Static equilibrium at every instant, each started from its neighbour's: robust for large strokes.
  const int m = model_.unknown_count();
  const int n = static_cast<int>(input.values.size());
  Eigen::MatrixXd z(m, n);
  std::vector<double> previous;
  for (int mu = 0; mu < n; ++mu) {
    previous = model_.StaticEquilibrium(input.values[mu], theta, previous);
    for (int j = 0; j < m; ++j) z(j, mu) = previous[j];
  }
  return z;
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
  Prepare(n);
  lu_valid_ = false;

  Eigen::MatrixXd z;
  if (warm_start && warm_start->n == n && warm_start->unknowns.rows() == m) {
    z = warm_start->unknowns;
  } else {
    try {
      z = MarchGuess(QuasiStaticGuess(input, theta), input, theta, options_.start_up_periods);
    } catch (const ModelError& e) {
      throw PeriodicSolverError(fmt::format("periodic solver: no static-equilibrium guess: {}", e.what()), NAN, 0);
    }
  }
  Eigen::VectorXd step_scale(m);
  for (int j = 0; j < m; ++j) step_scale[j] = model_.unknown_spec(j).scale * options_.tolerance;

  Eigen::MatrixXd g = Residual(z, input, theta);
  double norm = g.allFinite() ? g.norm() : INFINITY;
  int iteration = 0;
  bool converged = false;
  for (; iteration < options_.max_iterations && !converged; ++iteration) {
    if (!std::isfinite(norm))
      throw PeriodicSolverError(
          fmt::format("periodic solver: non-finite residual at iteration {} (the guess is outside the model's range)",
                      iteration),
          norm, iteration);
    AssembleJacobian(z, input, theta);
    if (!lu_.Factorize(jacobian_))
      throw PeriodicSolverError(
          fmt::format("periodic solver: singular Jacobian at iteration {} (residual {:.3g})", iteration, norm), norm,
          iteration);
    lu_valid_ = true;
    Eigen::MatrixXd step = -g;
    lu_.Solve(Eigen::Map<Eigen::VectorXd>(step.data(), step.size()));
    converged = (step.array().abs().colwise() / step_scale.array()).maxCoeff() <= 1.0;
    // Step halving (Fey) with Deuflhard's natural monotonicity test: accept the first fraction
    // whose simplified Newton correction J^-1 G(trial) (same factorisation, scaled by the unknowns'
    // scales) shrinks. Unlike the residual norm this test does not depend on how the equations are
    // scaled, and it lets Newton cross the friction switches of force-driven problems in few steps.
    const auto scaled_norm = [&](const Eigen::MatrixXd& dz) {
      return (dz.array().colwise() / step_scale.array()).matrix().norm();
    };
    const double step_norm = scaled_norm(step);
    double lambda = 1.0;
    bool accepted = false;
    for (int halving = 0; halving <= options_.max_halvings; ++halving, lambda *= 0.5) {
      Eigen::MatrixXd trial = z + lambda * step;
      Eigen::MatrixXd g_trial = Residual(trial, input, theta);
      const double trial_norm = g_trial.allFinite() ? g_trial.norm() : INFINITY;
      bool descent = converged;
      if (!descent && std::isfinite(trial_norm)) {
        Eigen::MatrixXd correction = -g_trial;
        lu_.Solve(Eigen::Map<Eigen::VectorXd>(correction.data(), correction.size()));
        descent = scaled_norm(correction) <= (1.0 - 0.25 * lambda) * step_norm;
        // After a full step the simplified correction is the size of the next Newton step: when it
        // is below the tolerance already, that step need not be taken.
        if (descent && lambda == 1.0 &&
            (correction.array().abs().colwise() / step_scale.array()).maxCoeff() <= 1.0)
          converged = true;
      }
      if (descent) {
        z = std::move(trial);
        g = std::move(g_trial);
        norm = trial_norm;
        accepted = true;
        break;
      }
    }
    if (!accepted)
      throw PeriodicSolverError(
          fmt::format("periodic solver: no descent after {} step halvings at iteration {}; scaled residual {:.3g} "
                      "(no periodic solution near the guess)",
                      options_.max_halvings, iteration, norm),
          norm, iteration);
    spdlog::trace("periodic Newton {}: residual {:.3e} step {}", iteration, norm, lambda);
  }
  if (!converged || !g.allFinite())
    throw PeriodicSolverError(fmt::format("periodic solver: not converged after {} iterations; scaled residual {:.3g}",
                                          iteration, norm),
                              norm, iteration);

  last_unknowns_ = z;
  PeriodicSolution solution;
  solution.scheme = options_.scheme;
  solution.frequency = input.frequency;
  solution.n = n;
  solution.unknowns = std::move(z);
  solution.input = input;
  solution.newton_iterations = iteration;
  solution.residual_norm = g.lpNorm<Eigen::Infinity>();
  solution.channels = model_.output_channels();
  solution.outputs.resize(static_cast<int>(solution.channels.size()), n);
  std::vector<double> y(solution.channels.size());
  for (int mu = 0; mu < n; ++mu) {
    model_.Outputs<double>(std::span<const double>(solution.unknowns.col(mu).data(), m), input.values[mu], theta, y);
    for (std::size_t c = 0; c < y.size(); ++c) solution.outputs(static_cast<int>(c), mu) = y[c];
  }
  if (!solution.outputs.allFinite())
    throw PeriodicSolverError("periodic solver: non-finite outputs at the solution", norm, iteration);
  return solution;
}

std::vector<Eigen::MatrixXd> PeriodicSolver::OutputSensitivities(const PeriodicSolution& solution,
                                                                 std::span<const double> theta) {
  const int m = model_.unknown_count();
  const int n = solution.n;
  const int np = model_.parameter_count();
  Prepare(n);
  if (!lu_valid_ || last_unknowns_.cols() != n || last_unknowns_ != solution.unknowns) {
    // Not the solution of the last Solve (a caller restored an older one): factorise at it.
    AssembleJacobian(solution.unknowns, solution.input, theta);
    if (!lu_.Factorize(jacobian_))
      throw PeriodicSolverError("periodic solver: singular Jacobian at the solution (sensitivities)", 0.0, 0);
    lu_valid_ = true;
    last_unknowns_ = solution.unknowns;
  }
  const PeriodicInput& input = solution.input;
  const auto input_rates = InputRates(stencil_, input);
  std::vector<Jet> theta_jet(np);
  for (int i = 0; i < np; ++i) theta_jet[i] = Jet(theta[i], DerivativeVector::Unit(np, i));
  // dG/dtheta at the solution, scaled like G.
  Eigen::MatrixXd rhs(n * m, np);
  std::vector<Jet> x(m), xd(m), xdd(m), r(m);
  const auto& z = solution.unknowns;
  for (int mu = 0; mu < n; ++mu) {
    for (int j = 0; j < m; ++j) {
      const Rates rate = RatesAt(stencil_, z.row(j), mu, n, input.frequency);
      x[j] = MakeConstant(z(j, mu), np);
      xd[j] = MakeConstant(rate.first, np);
      xdd[j] = MakeConstant(rate.second, np);
    }
    model_.Residual<Jet>(x, xd, xdd, MakeConstant(input.values[mu], np), MakeConstant(input_rates[mu].first, np),
                         MakeConstant(input_rates[mu].second, np), theta_jet, r);
    for (int i = 0; i < m; ++i) {
      const auto& d = r[i].derivatives();
      for (int p = 0; p < np; ++p)
        rhs(mu * m + i, p) = d.size() == np ? -d[p] / model_.equation_scale(i) : 0.0;
    }
  }
  lu_.Solve(rhs);  // rhs now holds dz/dtheta (eq. 14)
  const int channels = static_cast<int>(solution.channels.size());
  std::vector<Eigen::MatrixXd> sens(channels, Eigen::MatrixXd(n, np));
  std::vector<Jet> xs(m), y(channels);
  for (int mu = 0; mu < n; ++mu) {
    for (int j = 0; j < m; ++j) xs[j] = Jet(z(j, mu), rhs.row(mu * m + j).transpose());
    model_.Outputs<Jet>(xs, MakeConstant(input.values[mu], np), theta_jet, y);  // eq. 15
    for (int c = 0; c < channels; ++c) {
      const auto& d = y[c].derivatives();
      for (int p = 0; p < np; ++p) sens[c](mu, p) = d.size() == np ? d[p] : 0.0;
    }
  }
  return sens;
}

}  // namespace strut::ident
