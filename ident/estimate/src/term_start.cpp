#include "strut/ident/term_start.h"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <functional>
#include <optional>
#include <stdexcept>

#include "strut/ident/periodic.h"
#include "strut/ident/catalogue.h"

namespace strut::ident {
namespace {

// One averaged sample of one experiment: the measured signals the force terms are written in, and
// the force equation error (the force residual less theta4 times the pressure residual: the force
// balance with the measured pressure) with its weight (1 / noise sd).
struct Sample {
  double q = 0.0, rate = 0.0, accel = 0.0, p = 0.0;
  double force_error = 0.0, force_weight = 0.0;
};

// The baseline's parameter values by paper index.
class Values {
 public:
  explicit Values(const FitSummary& fit) : fit_(fit) {}
  bool has(int index) const { return fit_.parameters.position_of_index(index) >= 0; }
  double at(int index, double fallback = 0.0) const {
    const int p = fit_.parameters.position_of_index(index);
    return p >= 0 ? fit_.parameters.value(p) : fallback;
  }
  //! The baseline estimated theta<index>: its sensitivity belongs among the regressors.
  bool estimated(int index) const {
    const int p = fit_.parameters.position_of_index(index);
    return p >= 0 && p < static_cast<int>(fit_.estimates.size()) && fit_.estimates[p].estimated;
  }

 private:
  const FitSummary& fit_;
};

std::vector<Sample> Collect(const FitSummary& fit, const Values& v) {
  std::vector<Sample> out;
  const double area = v.at(4), offset = v.at(12);
  for (const ExperimentFit& e : fit.experiments) {
    if (!e.converged) continue;
    const auto channel = [&](const std::map<std::string, Eigen::VectorXd>& m, const char* name) {
      const auto it = m.find(name);
      return it != m.end() && it->second.size() == static_cast<Eigen::Index>(e.phases.size()) ? &it->second : nullptr;
    };
    const Eigen::VectorXd *stroke = channel(e.measured, "stroke"), *pressure = channel(e.measured, "pressure"),
                          *rf = channel(e.residual, "force"), *rp = channel(e.residual, "pressure");
    if (!stroke || !pressure) continue;
    const auto variance = [&](const char* name) {
      const auto it = e.noise_variance.find(name);
      return it != e.noise_variance.end() && it->second > 0 ? it->second : NAN;
    };
    const double vf = variance("force"), vp = variance("pressure");
    const PeriodicSeries series = PeriodicSeries::Fit(*stroke, e.frequency);
    const int count = static_cast<int>(e.phases.size());
    const Eigen::VectorXd rate = series.OnPhases(count, 1), accel = series.OnPhases(count, 2);
    for (int i = 0; i < count; ++i) {
      Sample s;
      s.q = (*stroke)[i] - offset;
      s.rate = rate[i];
      s.accel = accel[i];
      s.p = (*pressure)[i];
      if (rf && std::isfinite(vf)) {
        const double r_p = rp ? (*rp)[i] : 0.0;
        s.force_error = (*rf)[i] - area * r_p;
        s.force_weight = 1.0 / std::sqrt(vf + (rp && std::isfinite(vp) ? area * area * vp : 0.0));
      }
      out.push_back(s);
    }
  }
  return out;
}

using Column = std::function<double(const Sample&)>;

struct Regression {
  bool ok = false;
  double coefficient = 0.0;  // of the first column
  double rss = INFINITY;     // weighted residual sum of squares
  double t = 0.0;            // coefficient over its standard error
};

// Least squares of b on the unit-norm columns of a (scaled by `norm` from the original ones); the
// first column's coefficient, the residual sum of squares and the coefficient's t. Nuisance columns
// that are collinear (a solubility and a stroke offset at one temperature) are dropped by the QR.
Regression& Solve(const Eigen::MatrixXd& a, const Eigen::VectorXd& b, const Eigen::VectorXd& norm, Regression& r) {
  const Eigen::Index k = a.cols();
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(a);
  const Eigen::VectorXd x = qr.solve(b);
  r.rss = (a * x - b).squaredNorm();
  r.coefficient = x[0] / norm[0];
  // The first column's standard error: its distance from the span of the other kept columns.
  if (k > 1) {
    const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> rest(a.rightCols(k - 1));
    const Eigen::VectorXd projection = a.rightCols(k - 1) * rest.solve(a.col(0));
    const double distance = (a.col(0) - projection).norm();
    const double sd = std::sqrt(r.rss / std::max<Eigen::Index>(1, a.rows() - qr.rank())) / distance;
    r.t = distance > 0 && sd > 0 ? x[0] / sd : 0.0;
  } else {
    const double sd = std::sqrt(r.rss / std::max<Eigen::Index>(1, a.rows() - 1));
    r.t = sd > 0 ? x[0] / sd : 0.0;
  }
  r.ok = std::isfinite(r.coefficient);
  return r;
}

// Weighted least squares of the force equation error on `columns`: the first column is the
// candidate's force, the others the baseline's nuisance directions.
Regression Regress(const std::vector<Sample>& samples, const std::vector<Column>& columns) {
  Regression r;
  std::vector<const Sample*> used;
  for (const Sample& s : samples)
    if (s.force_weight > 0) used.push_back(&s);
  const Eigen::Index m = static_cast<Eigen::Index>(used.size()), k = static_cast<Eigen::Index>(columns.size());
  if (m < 4 * k + 8) return r;
  Eigen::MatrixXd a(m, k);
  Eigen::VectorXd b(m);
  for (Eigen::Index i = 0; i < m; ++i) {
    const Sample& s = *used[i];
    for (Eigen::Index j = 0; j < k; ++j) a(i, j) = s.force_weight * columns[j](s);
    b[i] = s.force_weight * s.force_error;
  }
  // Columns scaled to unit norm so that the QR's rank decision is about directions, not units.
  Eigen::VectorXd norm = a.colwise().norm().transpose();
  if (!(norm[0] > 0)) return r;
  for (Eigen::Index j = 0; j < k; ++j)
    if (norm[j] > 0) a.col(j) /= norm[j];
  return Solve(a, b, norm, r);
}

// Least squares of b on one column beside fixed nuisance columns, for many such columns (a search
// over a shape): the nuisance is factorised once, and each column is regressed on what the nuisance
// leaves of it and of b (Frisch-Waugh-Lovell), which gives the joint regression's coefficient,
// residual sum of squares and t at the cost of two projections.
class ProjectedRegression {
 public:
  ProjectedRegression() = default;
  ProjectedRegression(Eigen::MatrixXd nuisance, const Eigen::VectorXd& b) {
    // Columns scaled to unit norm so that the QR's rank decision is about directions, not units.
    for (Eigen::Index j = 0; j < nuisance.cols(); ++j)
      if (const double norm = nuisance.col(j).norm(); norm > 0) nuisance.col(j) /= norm;
    const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(nuisance);
    basis_ = qr.householderQ() * Eigen::MatrixXd::Identity(nuisance.rows(), qr.rank());
    left_ = b - basis_ * (basis_.transpose() * b);
    ok_ = true;
  }

  Regression Fit(const Eigen::VectorXd& c) const {
    Regression r;
    const double norm = c.norm();
    if (!ok_ || !(norm > 0)) return r;
    const Eigen::VectorXd c_left = c - basis_ * (basis_.transpose() * c);
    const double distance2 = c_left.squaredNorm();
    if (!(distance2 > 1e-24 * norm * norm)) return r;  // in the nuisance's span: no coefficient of its own
    const double along = c_left.dot(left_);
    r.coefficient = along / distance2;
    r.rss = std::max(left_.squaredNorm() - along * along / distance2, 0.0);
    const double sd = std::sqrt(r.rss / std::max<Eigen::Index>(1, c.size() - basis_.cols() - 1));
    r.t = sd > 0 ? along / std::sqrt(distance2) / sd : 0.0;
    r.ok = std::isfinite(r.coefficient);
    return r;
  }

 private:
  Eigen::MatrixXd basis_;  // orthonormal, spanning the nuisance columns
  Eigen::VectorXd left_;   // b less its projection on them
  bool ok_ = false;
};

// Regress with one set of nuisance columns and many first columns (the end stop's position search).
class NuisanceRegression {
 public:
  NuisanceRegression(const std::vector<Sample>& samples, const std::vector<Column>& nuisance) {
    for (const Sample& s : samples)
      if (s.force_weight > 0) used_.push_back(&s);
    const Eigen::Index m = static_cast<Eigen::Index>(used_.size()), k = static_cast<Eigen::Index>(nuisance.size());
    if (m < 4 * (k + 1) + 8) return;
    Eigen::MatrixXd a(m, k);
    Eigen::VectorXd b(m);
    for (Eigen::Index i = 0; i < m; ++i) {
      for (Eigen::Index j = 0; j < k; ++j) a(i, j) = used_[i]->force_weight * nuisance[j](*used_[i]);
      b[i] = used_[i]->force_weight * used_[i]->force_error;
    }
    regression_ = ProjectedRegression(std::move(a), b);
  }

  Regression Fit(const Column& first) const {
    Eigen::VectorXd c(static_cast<Eigen::Index>(used_.size()));
    for (Eigen::Index i = 0; i < c.size(); ++i) c[i] = used_[i]->force_weight * first(*used_[i]);
    return regression_.Fit(c);
  }

 private:
  std::vector<const Sample*> used_;
  ProjectedRegression regression_;
};

// The force balance's sensitivities to the parameters the baseline estimated (method.md eq. 21).
std::vector<Column> ForceNuisance(const Values& v) {
  std::vector<Column> c;
  const double sharpness = v.at(10), base = v.at(8), per_pressure = v.at(9), gravity = v.at(2, 9.81);
  if (v.estimated(1)) c.push_back([=](const Sample& s) { return s.accel + gravity; });
  if (v.estimated(3)) c.push_back([](const Sample& s) { return s.rate * std::abs(s.rate); });
  if (v.estimated(4)) c.push_back([](const Sample& s) { return s.p; });
  if (v.estimated(8)) c.push_back([=](const Sample& s) { return std::atan(sharpness * s.rate); });
  if (v.estimated(9)) c.push_back([=](const Sample& s) { return s.p * std::atan(sharpness * s.rate); });
  if (v.estimated(10))
    c.push_back([=](const Sample& s) {
      const double x = sharpness * s.rate;
      return (base + per_pressure * s.p) * s.rate / (1.0 + x * x);
    });
  if (v.estimated(11) || !v.has(11)) c.push_back([](const Sample&) { return 1.0; });
  if (v.estimated(18)) c.push_back([](const Sample& s) { return s.rate; });
  return c;
}

// One Gauss-Newton step from the baseline into `candidate` with the size at 0 (where, by design,
// the candidate is the baseline and its residual is nearly linear in the size): the fitted
// channels' residuals regressed on the exact periodic sensitivities to the size and to every
// parameter the baseline estimated, weighted by the noise. `theta` holds the candidate's values.
// Over the values of a shape parameter that, with the size at 0, changes nothing (a Stribeck width
// at zero excess) the solutions and the nuisance sensitivities stay the same: they are made and
// factorised once, and each value costs the size's own sensitivity (on the solutions' kept
// factorisations) and a ProjectedRegression.
class SizeStep {
 public:
  SizeStep(const FitSummary& baseline, const Model& model, const std::vector<double>& theta, int size_position,
           std::vector<std::string>& problems)
      : size_(size_position) {
    std::vector<int> nuisance;
    for (int i = 0; i < baseline.parameters.size(); ++i)
      if (i < static_cast<int>(baseline.estimates.size()) && baseline.estimates[i].estimated)
        if (const auto p = model.defaults().find(baseline.parameters.spec(i).key())) nuisance.push_back(*p);
    std::vector<Eigen::MatrixXd> blocks;
    std::vector<Eigen::VectorXd> targets;
    for (const ExperimentFit& e : baseline.experiments) {
      if (!e.converged || e.solution.n == 0) continue;
      PeriodicSolverOptions options;
      options.scheme = e.solution.scheme;
      Experiment x{PeriodicSolver(model, options), {}, model.AtExperiment(theta, {e.session_time, e.static_position}), {}};
      std::vector<Eigen::MatrixXd> sensitivities;
      try {
        x.solution = x.solver.Solve(e.solution.input, x.at, &e.solution);
        sensitivities = x.solver.OutputSensitivities(x.solution, x.at, nuisance);
      } catch (const PeriodicSolverError& ex) {
        problems.push_back(fmt::format("experiment '{}': {}", e.label, ex.what()));
        continue;
      }
      for (const auto& [channel, residual] : e.residual) {
        const auto variance = e.noise_variance.find(channel);
        const auto row = std::find(x.solution.channels.begin(), x.solution.channels.end(), channel);
        if (variance == e.noise_variance.end() || !(variance->second > 0) || row == x.solution.channels.end()) continue;
        const int r = static_cast<int>(row - x.solution.channels.begin());
        const double w = 1.0 / std::sqrt(variance->second);
        x.channels.push_back({r, PhaseInterpolation::Cubic(x.solution.input.phases, x.solution.n, e.phases), w});
        blocks.push_back(w * x.channels.back().map.Columns(sensitivities[r]));
        targets.push_back(w * residual);
      }
      experiments_.push_back(std::move(x));
    }
    for (const auto& b : blocks) rows_ += b.rows();
    if (rows_ < 8 * static_cast<Eigen::Index>(nuisance.size() + 1)) return;
    Eigen::MatrixXd a(rows_, static_cast<Eigen::Index>(nuisance.size()));
    Eigen::VectorXd b(rows_);
    Eigen::Index at = 0;
    for (std::size_t i = 0; i < blocks.size(); ++i) {
      a.middleRows(at, blocks[i].rows()) = blocks[i];
      b.segment(at, blocks[i].rows()) = targets[i];
      at += blocks[i].rows();
    }
    regression_ = ProjectedRegression(std::move(a), b);
  }

  //! The size's step and t.
  Regression At() { return At(-1, 0.0); }
  //! The size's step and t with the shape parameter at `shape_position` at `value`.
  Regression At(int shape_position, double value) {
    Eigen::VectorXd c(rows_);
    Eigen::Index at = 0;
    for (Experiment& x : experiments_) {
      if (shape_position >= 0) x.at[shape_position] = value;
      const std::vector<Eigen::MatrixXd> sensitivity =
          x.solver.OutputSensitivities(x.solution, x.at, std::span<const int>(&size_, 1));
      for (const Channel& ch : x.channels) {
        const Eigen::MatrixXd column = ch.weight * ch.map.Columns(sensitivity[ch.row]);
        c.segment(at, column.rows()) = column.col(0);
        at += column.rows();
      }
    }
    return regression_.Fit(c);
  }

 private:
  struct Channel {
    int row;
    PhaseInterpolation map;
    double weight;
  };
  struct Experiment {
    PeriodicSolver solver;
    PeriodicSolution solution;
    std::vector<double> at;
    std::vector<Channel> channels;
  };
  int size_;
  std::vector<Experiment> experiments_;
  Eigen::Index rows_ = 0;
  ProjectedRegression regression_;
};

// log(1 + e^x) without overflow, as the end-stop term.
double Softplus(double x) { return x > 0 ? x + std::log1p(std::exp(-x)) : std::log1p(std::exp(x)); }

}  // namespace

namespace {

// The end stop's stiffness regressed at each position from 2 mm outside the least stroke `q_min` to
// 30 mm inside it, 0.1 mm apart: the stop position is the largest stroke from which down the
// extension-end force residual grows. Returns the regression with the least residual and its position.
std::pair<Regression, double> EndStopSearch(const std::vector<Sample>& samples, const Values& v, double q_min,
                                            double smoothing, double dissipation) {
  Regression best;
  double position = NAN;
  const NuisanceRegression regression(samples, ForceNuisance(v));
  for (double x = q_min - 2e-3; x <= q_min + 30e-3; x += 1e-4) {
    const Regression r = regression.Fit([=](const Sample& s) {
      const double d = smoothing * Softplus((x - s.q) / smoothing);
      return -d * (1.0 - dissipation * s.rate);
    });
    if (r.ok && r.coefficient > 0 && r.rss < best.rss) best = r, position = x;
  }
  return {best, position};
}

// The sizing parameter (paper index) of a term whose start is one Gauss-Newton step on its size
// alone (no shape parameter to search), 0 for the other terms.
int GaussNewtonSizeIndex(const std::string& term) {
  static const std::pair<const char*, int> sizes[] = {
      {"gas-solubility", 7},       {"oil-compressibility", 26},    {"real-gas", 31},
      {"recoil-damping", 32},      {"metering-pin", 33},           {"friction-asymmetry", 34},
      {"pressure-heat-transfer", 35}, {"dead-volume", 36},         {"charge-loss", 37}};
  for (const auto& [name, index] : sizes)
    if (term == name) return index;
  return 0;
}

}  // namespace

CandidateStart CandidateStartingValues(const std::string& term, const FitSummary& baseline,
                                       std::vector<std::string>* log) {
  const auto& catalogue = Catalogue();
  if (std::none_of(catalogue.begin(), catalogue.end(), [&](const TermEntry& e) { return e.name == term; }))
    throw std::invalid_argument(fmt::format("CandidateStartingValues: '{}' is not a catalogue term", term));
  const auto note = [&](const std::string& line) {
    if (log) log->push_back(line);
  };
  // The candidate model gives the term's parameters: their defaults (for the fixed ones the
  // sensitivities need) and their ranges.
  std::optional<Model> built;
  try {
    built.emplace(Model::Build(baseline.model + "+" + term, Causality::kStrokeInput));
  } catch (const ModelError& e) {  // the baseline and the term make no catalogue model
    note(fmt::format("{}: no starting values: {}", term, e.what()));
    return {};
  }
  const Model& model = *built;
  const ParameterSet& candidate = model.defaults();
  // The candidate's values: the baseline's where it has the parameter, else the defaults.
  const auto baseline_values = [&] {
    std::vector<double> theta = candidate.values();
    for (int i = 0; i < candidate.size(); ++i)
      if (const auto p = baseline.parameters.find(candidate.spec(i).key())) theta[i] = baseline.parameters.value(*p);
    return theta;
  };
  const Values v(baseline);
  const auto own = [&](int index, double fallback) {
    // The baseline's value when it has the parameter, else the candidate's default.
    if (v.has(index)) return v.at(index);
    const int p = candidate.position_of_index(index);
    return p >= 0 ? candidate.value(p) : fallback;
  };
  const std::vector<Sample> samples = Collect(baseline, v);
  CandidateStart start;
  std::vector<std::pair<std::string, double>>& out = start.values;
  const auto give = [&](int index, double value, const std::string& how) {
    const int p = candidate.position_of_index(index);
    if (p < 0 || !std::isfinite(value)) return;
    const ParameterSpec& spec = candidate.spec(p);
    if (!spec.range.contains(value)) {
      const double clipped = std::isfinite(spec.range.lower) && value < spec.range.lower ? spec.range.lower : spec.range.upper;
      if (!spec.range.contains(clipped)) return;
      note(fmt::format("{} {} = {:.4g} {} clipped into {} from {:.4g} ({})", spec.key(), spec.name, clipped, spec.unit,
                       spec.range.ToString(), value, how));
      value = clipped;
    } else {
      note(fmt::format("{} {} = {:.4g} {} ({})", spec.key(), spec.name, value, spec.unit, how));
    }
    out.emplace_back(spec.key(), value);
  };
  const auto with = [](Column first, std::vector<Column> rest) {
    rest.insert(rest.begin(), std::move(first));
    return rest;
  };

  if (term == "viscous-damping") {
    const Regression r = Regress(samples, with([](const Sample& s) { return s.rate; }, ForceNuisance(v)));
    if (r.ok) give(18, r.coefficient, fmt::format("force equation error on the stroke rate, t {:+.1f}", r.t));
    if (r.ok) start.size_score = r.t;
  } else if (term == "stribeck-friction") {
    // The excess is linear at 0, the width is not: one Gauss-Newton step for the excess at each
    // width of a log grid, 20 % apart from 0.5 to 40 mm/s; the width whose step leaves the least
    // residual. (The force equation error alone would lose the part of the excess the baseline's
    // friction level and sharpness absorbed, whose linearisation is poor this far from the truth.)
    std::vector<double> theta = baseline_values();
    const int excess = candidate.position_of_index(19), velocity = candidate.position_of_index(20);
    theta[excess] = 0.0;
    Regression best;
    double width = NAN;
    std::vector<std::string> problems;
    SizeStep step(baseline, model, theta, excess, problems);
    for (double w = 5e-4; w <= 4e-2; w *= 1.2) {
      const Regression r = step.At(velocity, w);
      if (r.ok && r.coefficient > 0 && r.rss < best.rss) best = r, width = w;
    }
    for (const auto& p : problems) note(fmt::format("{}: left out: {}", term, p));
    if (best.ok) {
      give(19, best.coefficient, fmt::format("one Gauss-Newton step from the baseline with the excess at 0, t {:+.1f}",
                                             best.t));
      give(20, width, "the width in stroke rate whose step explains the residual best");
      start.size_score = best.t;
    } else {
      note("stribeck-friction: no width gives a positive excess; defaults kept");
    }
  } else if (term == "end-stop") {
    double q_min = INFINITY;
    for (const Sample& s : samples)
      if (s.force_weight > 0) q_min = std::min(q_min, s.q);
    const auto [best, position] = EndStopSearch(samples, v, q_min, own(24, 1e-4), own(22, 0.0));
    if (best.ok) {
      give(23, position, fmt::format("least residual over stop positions near the least stroke {:.4f} m", q_min));
      give(21, best.coefficient, fmt::format("force equation error on the penetration, t {:+.1f}", best.t));
      start.size_score = best.t;
    } else {
      note("end-stop: no position gives a positive stiffness; defaults kept");
    }
  } else if (const int index = GaussNewtonSizeIndex(term); index > 0) {
    // Sizes that act through the gas law, the heat balance or the orifice and friction levels: the
    // pressure and force residuals on the exact sensitivity to the size at 0, next to those of the
    // parameters the baseline estimated.
    std::vector<double> theta = baseline_values();
    const int size = candidate.position_of_index(index);
    theta[size] = 0.0;
    std::vector<std::string> problems;
    const Regression r = SizeStep(baseline, model, theta, size, problems).At();
    for (const auto& p : problems) note(fmt::format("{}: left out: {}", term, p));
    if (r.ok) {
      give(index, r.coefficient,
           fmt::format("one Gauss-Newton step from the baseline with the size at 0, t {:+.1f}", r.t));
      start.size_score = r.t;
    }
  } else {
    note(fmt::format("{}: no rule for starting values; defaults kept", term));
  }
  return start;
}

CandidateStart DiscrepancyStartingValue(const Model& model, int index, const FitSummary& baseline,
                                        std::vector<std::string>* log) {
  CandidateStart start;
  const ParameterSet& candidate = model.defaults();
  const int size = candidate.position_of_index(index);
  if (size < 0) return start;
  std::vector<double> theta = candidate.values();
  for (int i = 0; i < candidate.size(); ++i)
    if (const auto p = baseline.parameters.find(candidate.spec(i).key())) theta[i] = baseline.parameters.value(*p);
  theta[size] = 0.0;
  std::vector<std::string> problems;
  SizeStep step(baseline, model, theta, size, problems);
  Regression r = step.At();
  // A function with a shape (the heat flow's exponent, a contact's position) is linear in its
  // coefficient only: one step at each shape of its grid, the shape whose step leaves the least
  // residual.
  const auto function = std::find_if(DiscrepancyLibrary().begin(), DiscrepancyLibrary().end(),
                                     [&](const DiscrepancyFunction& f) { return f.index == index; });
  const int shape = function != DiscrepancyLibrary().end() && function->shape_index
                        ? candidate.position_of_index(function->shape_index)
                        : -1;
  double shape_value = NAN;
  if (shape >= 0)
    for (const double value : function->shape_grid) {
      const Regression at = step.At(shape, value);
      if (at.ok && at.rss < (std::isfinite(shape_value) ? r.rss : INFINITY)) r = at, shape_value = value;
    }
  if (log) {
    for (const auto& p : problems) log->push_back(fmt::format("{}: left out: {}", candidate.spec(size).name, p));
    if (r.ok)
      log->push_back(fmt::format("{} {} = {:.4g} (one Gauss-Newton step from the baseline with it at 0, t {:+.1f}){}",
                                 candidate.spec(size).key(), candidate.spec(size).name, r.coefficient, r.t,
                                 std::isfinite(shape_value) ? fmt::format(" with its shape at {:g}", shape_value) : ""));
  }
  if (r.ok && std::isfinite(r.coefficient)) {
    start.values.emplace_back(candidate.spec(size).key(), r.coefficient);
    if (std::isfinite(shape_value)) start.values.emplace_back(candidate.spec(shape).key(), shape_value);
    start.size_score = r.t;
  }
  return start;
}

}  // namespace strut::ident
