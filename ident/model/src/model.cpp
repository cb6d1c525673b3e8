#include "strut/ident/model.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <fmt/format.h>
#include <set>
#include <type_traits>

#include "strut/ident/catalogue.h"

namespace strut::ident {
namespace {
constexpr double kForceScale = 1e-6;  // N: a force-balance residual too small to matter
// The damper's mechanical slots. Scales are changes too small to matter: Newton stops below them.
const StateSpec kStrokeSlot{"stroke", "m", 2, 0.1, 1e-9, kForceScale};
const StateSpec kForceSlot{"force", "N", 0, 5.0e3, 1e-6, kForceScale};
// Bases in the order the canonical name prefers them (the largest damper base first).
constexpr std::string_view kBases[] = {"2dof", "1dof", "linear-oscillator"};
}  // namespace

std::string_view ToString(Causality c) { return c == Causality::kForceInput ? "force" : "stroke"; }

Causality ParseCausality(std::string_view text) {
  if (text == "force") return Causality::kForceInput;
  if (text == "stroke") return Causality::kStrokeInput;
  throw ModelError(fmt::format("input must be 'force' or 'stroke', not '{}'", text));
}

void ModelBuilder::add_parameter(const ParameterSpec& spec) {
  for (const auto& p : parameters_) {
    if (p.index != spec.index) continue;
    if (p.name != spec.name)
      throw ModelError(fmt::format("terms disagree on theta{}: '{}' and '{}'", spec.index, p.name, spec.name));
    return;
  }
  parameters_.push_back(spec);
}

void ModelBuilder::add_state(const StateSpec& spec) {
  for (const auto& s : states_)
    if (s.name == spec.name) return;
  states_.push_back(spec);
}

int ModelBuilder::parameter_position(int index) const {
  for (std::size_t i = 0; i < parameters_.size(); ++i)
    if (parameters_[i].index == index) return static_cast<int>(i);
  throw ModelError(fmt::format("the model has no theta{} that a term needs", index));
}

int ModelBuilder::state_position(std::string_view state, std::string_view needed_by) const {
  for (std::size_t i = 0; i < states_.size(); ++i)
    if (states_[i].name == state) return static_cast<int>(i);
  throw ModelError(fmt::format("term '{}' needs the state '{}', which no term of the model provides", needed_by, state));
}

bool ModelBuilder::has_state(std::string_view state) const {
  return std::any_of(states_.begin(), states_.end(), [&](const StateSpec& s) { return s.name == state; });
}

bool ModelBuilder::has_term(std::string_view term) const {
  return std::find(term_names_.begin(), term_names_.end(), term) != term_names_.end();
}

void ModelBuilder::declare_channels(const StateSpec& displacement, const StateSpec& drive, std::string_view by) {
  if (displacement_ && (displacement_->name != displacement.name || drive_->name != drive.name))
    throw ModelError(fmt::format("terms '{}' and '{}' name the model's channels differently ({}/{} and {}/{})",
                                 channels_by_, by, displacement_->name, drive_->name, displacement.name, drive.name));
  displacement_ = displacement;
  drive_ = drive;
  channels_by_ = std::string(by);
}

void ModelBuilder::set_output_offset(int index) { output_offset_index_ = index; }

std::vector<std::string> Model::Catalogue() {
  std::vector<std::string> names = {"1dof", "2dof", "linear-oscillator"};
  for (const auto& e : ::strut::ident::Catalogue())
    if (std::find(names.begin(), names.end(), e.name) == names.end()) names.push_back(e.name);
  return names;
}

Model Model::Build(std::string_view composition, Causality causality) {
  const auto& catalogue = ::strut::ident::Catalogue();
  const auto catalogue_list = [&] {
    std::string s;
    for (const auto& n : Model::Catalogue()) s += " " + n;
    return s;
  };
  std::vector<std::string> tokens;
  for (std::size_t start = 0;;) {
    const std::size_t plus = composition.find('+', start);
    tokens.emplace_back(composition.substr(start, plus == std::string_view::npos ? plus : plus - start));
    if (plus == std::string_view::npos) break;
    start = plus + 1;
  }
  const auto& base = BaseTerms(tokens.front());
  if (base.empty())
    throw ModelError(fmt::format("model '{}': the base must be 1dof, 2dof or linear-oscillator, not '{}'", composition,
                                 tokens.front()));
  std::set<std::string> chosen(base.begin(), base.end());
  for (std::size_t i = 1; i < tokens.size(); ++i) {
    const auto it = std::find_if(catalogue.begin(), catalogue.end(), [&](const TermEntry& e) { return e.name == tokens[i]; });
    if (it == catalogue.end())
      throw ModelError(fmt::format("model '{}': unknown term '{}'; the catalogue has:{}", composition, tokens[i], catalogue_list()));
    if (std::find(std::begin(kBases), std::end(kBases), tokens[i]) != std::end(kBases) &&
        !BaseTerms(tokens.front()).empty() && !chosen.count(it->name))
      throw ModelError(fmt::format("model '{}': '{}' is a base of its own; start the composition with it", composition,
                                   tokens[i]));
    if (!chosen.insert(it->name).second)
      throw ModelError(fmt::format("model '{}': term '{}' is already in the model", composition, tokens[i]));
    if (!it->replaces.empty()) chosen.erase(it->replaces);
  }

  Model model;
  model.causality_ = causality;
  ModelBuilder builder;
  std::vector<std::shared_ptr<Term>> terms;
  for (const auto& entry : catalogue) {  // catalogue order is evaluation order
    if (!chosen.count(entry.name)) continue;
    terms.push_back(entry.make());
    builder.term_names_.push_back(entry.name);
  }
  for (auto& t : terms) t->Declare(builder);
  std::stable_sort(builder.parameters_.begin(), builder.parameters_.end(),
                   [](const ParameterSpec& a, const ParameterSpec& b) { return a.index < b.index; });
  for (auto& t : terms) t->Bind(builder);

  // Canonical name: the largest base the term set contains, plus the rest in catalogue order.
  const auto contains = [&](const std::vector<std::string>& set) {
    return std::all_of(set.begin(), set.end(), [&](const std::string& n) { return chosen.count(n) > 0; });
  };
  std::string base_name(tokens.front());
  for (std::string_view b : kBases)
    if (contains(BaseTerms(b))) {
      base_name = std::string(b);
      break;
    }
  const auto& base_set = BaseTerms(base_name);
  model.composition_ = base_name;
  for (const auto& n : builder.term_names_)
    if (std::find(base_set.begin(), base_set.end(), n) == base_set.end()) model.composition_ += "+" + n;

  model.term_names_ = builder.term_names_;
  model.terms_.assign(terms.begin(), terms.end());
  for (int phase = 0; phase < 3; ++phase)
    for (const auto& t : model.terms_)
      if (t->phases() & (1u << phase)) model.phase_terms_[phase].push_back(t.get());
  model.states_ = builder.states_;
  model.defaults_ = ParameterSet(builder.parameters_);
  model.displacement_ = builder.displacement_.value_or(kStrokeSlot);
  model.drive_ = builder.drive_.value_or(kForceSlot);
  model.displacement_.derivative_order = 2;
  model.drive_.derivative_order = 0;
  model.stroke_offset_position_ =
      builder.output_offset_index_ >= 0 ? builder.parameter_position(builder.output_offset_index_) : -1;
  model.session_time_position_ = model.defaults_.position_of_index(kSessionTimeIndex);
  model.static_position_position_ = model.defaults_.position_of_index(kStaticPositionIndex);
  return model;
}

std::vector<double> Model::AtExperiment(std::vector<double> theta, const ExperimentConditions& conditions) const {
  if (session_time_position_ >= 0) theta.at(session_time_position_) = conditions.session_time;
  if (static_position_position_ >= 0) theta.at(static_position_position_) = conditions.static_position;
  return theta;
}

bool Model::has_term(std::string_view name) const {
  return std::find(term_names_.begin(), term_names_.end(), name) != term_names_.end();
}

int Model::derivative_order(int j) const {
  if (j == 0) return causality_ == Causality::kForceInput ? 2 : 0;
  return states_.at(j - 1).derivative_order;
}

StateSpec Model::unknown_spec(int j) const {
  if (j > 0) return states_.at(j - 1);
  return causality_ == Causality::kForceInput ? displacement_ : drive_;
}

double Model::equation_scale(int j) const {
  return j == 0 ? drive_.equation_scale : states_.at(j - 1).equation_scale;
}

std::vector<std::string> Model::output_channels() const {
  std::vector<std::string> channels = {displacement_.name, drive_.name};
  for (const auto& s : states_) channels.push_back(s.name);
  return channels;
}

const std::string& Model::input_channel() const {
  return causality_ == Causality::kForceInput ? drive_.name : displacement_.name;
}

const std::string& Model::mechanical_channel() const {
  return causality_ == Causality::kForceInput ? displacement_.name : drive_.name;
}

std::string Model::channel_unit(std::string_view channel) const {
  if (channel == displacement_.name) return displacement_.unit;
  if (channel == drive_.name) return drive_.unit;
  for (const auto& s : states_)
    if (s.name == channel) return s.unit;
  throw ModelError(fmt::format("model '{}' has no output channel '{}'", composition_, channel));
}

template <typename S>
PointVariables<S> Model::Assemble(std::span<const S> x, std::span<const S> xd, std::span<const S> xdd, const S& u,
                                  const S& ud, const S& udd, std::span<const S> theta) const {
  PointVariables<S> v;
  if (causality_ == Causality::kForceInput) {
    v.stroke = x[0];
    v.stroke_rate = xd[0];
    v.stroke_accel = xdd[0];
    v.force = u;
  } else {
    // The measured stroke carries the sensor offset: true stroke = measured - theta12.
    v.stroke = stroke_offset_position_ >= 0 ? S(u - theta[stroke_offset_position_]) : u;
    v.stroke_rate = ud;
    v.stroke_accel = udd;
    v.force = x[0];
  }
  v.states = x.subspan(1);
  v.state_rates = xd.subspan(1);
  return v;
}

template <typename S>
void Model::Residuals(std::span<const S> x, std::span<const S> xd, std::span<const S> xdd, std::span<const S> u,
                      std::span<const S> ud, std::span<const S> udd, std::span<const S> theta, std::span<S> r) const {
  // Batches small enough for the stack and the cache; every term runs over a whole batch per phase.
  // Single instants (static solves, marching, the integrators) and the large runtime-size Jets go
  // one by one: a batch's arrays would cost more to set up than the calls they save.
  if (u.size() == 1 || std::is_same_v<S, Jet>) {
    ResidualBatches<S, 1>(x, xd, xdd, u, ud, udd, theta, r);
  } else {
    ResidualBatches<S, 32>(x, xd, xdd, u, ud, udd, theta, r);
  }
}

template <typename S, int kBatch>
void Model::ResidualBatches(std::span<const S> x, std::span<const S> xd, std::span<const S> xdd,
                            std::span<const S> u, std::span<const S> ud, std::span<const S> udd,
                            std::span<const S> theta, std::span<S> r) const {
  const int m = unknown_count();
  const int count = static_cast<int>(u.size());
  using Phase = typename TermContext<S>::Phase;
  static_assert(static_cast<int>(Phase::kGasState) == 0 && static_cast<int>(Phase::kBalance) == 2);
  std::array<PointVariables<S>, kBatch> v;
  std::array<TermContext<S>, kBatch> c;
  for (int start = 0; start < count; start += kBatch) {
    const int size = std::min(kBatch, count - start);
    for (int k = 0; k < size; ++k) {
      const std::size_t i = static_cast<std::size_t>(start + k), at = i * m;
      v[k] = Assemble(x.subspan(at, m), xd.subspan(at, m), xdd.subspan(at, m), u[i], ud[i], udd[i], theta);
      c[k].v = &v[k];
      c[k].theta = theta;
      const S zero = x[at] * 0.0;  // a Jet zero with the callers' derivative size
      c[k].force = zero;
      c[k].gas_volume = zero;
      c[k].gas_amount = zero;
      c[k].state_residuals = r.subspan(at + 1, m - 1);
    }
    const std::span<TermContext<S>> batch(c.data(), size);
    for (const Phase phase : {Phase::kGasState, Phase::kGasLaw, Phase::kBalance}) {
      for (auto& point : batch) point.phase = phase;
      for (const Term* t : phase_terms_[static_cast<int>(phase)]) t->Evaluate(batch);
    }
    for (int k = 0; k < size; ++k) r[static_cast<std::size_t>(start + k) * m] = c[k].force - v[k].force;
  }
}

template <typename S>
void Model::Residual(std::span<const S> x, std::span<const S> xd, std::span<const S> xdd, const S& u, const S& ud,
                     const S& udd, std::span<const S> theta, std::span<S> r) const {
  Residuals<S>(x, xd, xdd, std::span<const S>(&u, 1), std::span<const S>(&ud, 1), std::span<const S>(&udd, 1), theta,
               r);
}

template <typename S>
void Model::Outputs(std::span<const S> x, const S& u, std::span<const S> theta, std::span<S> y) const {
  if (causality_ == Causality::kForceInput) {
    y[0] = stroke_offset_position_ >= 0 ? S(x[0] + theta[stroke_offset_position_]) : x[0];
    y[1] = u;
  } else {
    y[0] = u;
    y[1] = x[0];
  }
  for (std::size_t j = 1; j < x.size(); ++j) y[j + 1] = x[j];
}

namespace {

// Model::StaticEquilibrium with Jets of type J: StateJet (fixed size, no copies of unused
// directions) when the unknowns fit, else Jet. The quasi-static guess calls it at every grid point.
template <class J>
std::vector<double> StaticEquilibriumWith(const Model& model, double input, std::span<const double> theta,
                                          std::span<const double> guess) {
  using Derivatives = typename J::DerType;
  const int m = model.unknown_count();
  const int directions = Derivatives::RowsAtCompileTime == Eigen::Dynamic ? m : int(Derivatives::RowsAtCompileTime);
  std::vector<double> x(m);
  for (int j = 0; j < m; ++j) x[j] = static_cast<int>(guess.size()) == m ? guess[j] : model.unknown_spec(j).typical_value;
  // Every Jet carries all directions: Eigen's AutoDiff cannot add an empty derivative to a full one.
  const auto constant = [&](double v) { return J(v, Derivatives::Zero(directions)); };
  std::vector<J> theta_jet;
  for (double t : theta) theta_jet.push_back(constant(t));
  std::vector<J> xj(m), zero(m, constant(0.0)), r(m);
  const J u = constant(input), zero_rate = constant(0.0);
  Eigen::VectorXd inverse_equation_scale(m);
  for (int i = 0; i < m; ++i) inverse_equation_scale[i] = 1.0 / model.equation_scale(i);
  const auto evaluate = [&](const std::vector<double>& at, Eigen::VectorXd& res, Eigen::MatrixXd* jac) {
    for (int j = 0; j < m; ++j) xj[j] = J(at[j], Derivatives::Unit(directions, j));
    model.Residual<J>(xj, zero, zero, u, zero_rate, zero_rate, theta_jet, r);
    for (int i = 0; i < m; ++i) {
      res[i] = r[i].value() * inverse_equation_scale[i];
      if (jac)
        for (int j = 0; j < m; ++j) (*jac)(i, j) = r[i].derivatives()[j] * inverse_equation_scale[i];
    }
  };
  Eigen::VectorXd scale(m);
  for (int j = 0; j < m; ++j) scale[j] = model.unknown_spec(j).scale;
  Eigen::MatrixXd jac(m, m);
  Eigen::VectorXd res(m), trial_res(m), step(m), correction(m);
  Eigen::FullPivLU<Eigen::MatrixXd> lu(m, m);
  std::vector<double> trial(m);
  evaluate(x, res, &jac);
  for (int iteration = 0; iteration < 100; ++iteration) {
    if (res.allFinite() && res.lpNorm<Eigen::Infinity>() < 1.0) return x;
    lu.compute(jac);
    step = lu.solve(-res);
    const double step_norm = step.cwiseQuotient(scale).norm();  // of the full Newton step
    // Trust limit: no unknown moves by more than half its size (plus half its typical value) at
    // once, so the linearised gas law cannot throw the stroke through full compression.
    double shrink = 1.0;
    for (int j = 0; j < m; ++j) {
      const double limit = 0.5 * (std::abs(x[j]) + std::abs(model.unknown_spec(j).typical_value));
      if (std::abs(step[j]) > limit && limit > 0) shrink = std::min(shrink, limit / std::abs(step[j]));
    }
    step *= shrink;
    // Natural monotonicity test (Deuflhard): the simplified correction must shrink. It keeps a
    // stiff gas law from throwing the stroke past full compression.
    double lambda = 1.0;
    for (int halving = 0; halving < 40; ++halving, lambda *= 0.5) {
      for (int j = 0; j < m; ++j) trial[j] = x[j] + lambda * step[j];
      evaluate(trial, trial_res, nullptr);
      if (!trial_res.allFinite()) continue;
      correction = lu.solve(-trial_res);
      if (correction.cwiseQuotient(scale).norm() <= (1.0 - 0.25 * lambda * shrink) * step_norm) {
        x = trial;
        break;
      }
    }
    if (lambda < 1e-11) break;
    evaluate(x, res, &jac);
  }
  if (res.allFinite() && res.lpNorm<Eigen::Infinity>() < 1e3) return x;  // close enough for a guess
  if (!res.allFinite())
    throw ModelError(fmt::format("model '{}': no static equilibrium for input {:.6g}: the model has no finite state "
                                 "there (beyond full compression?)",
                                 model.composition(), input));
  throw ModelError(fmt::format("model '{}': no static equilibrium found for input {:.6g} (scaled residual {:.3g})",
                               model.composition(), input, res.lpNorm<Eigen::Infinity>()));
}

}  // namespace

std::vector<double> Model::StaticEquilibrium(double input, std::span<const double> theta,
                                             std::span<const double> guess) const {
  if (unknown_count() <= kStateDirections) return StaticEquilibriumWith<StateJet>(*this, input, theta, guess);
  return StaticEquilibriumWith<Jet>(*this, input, theta, guess);
}

template void Model::Residuals<double>(std::span<const double>, std::span<const double>, std::span<const double>,
                                       std::span<const double>, std::span<const double>, std::span<const double>,
                                       std::span<const double>, std::span<double>) const;
template void Model::Residuals<Jet>(std::span<const Jet>, std::span<const Jet>, std::span<const Jet>,
                                    std::span<const Jet>, std::span<const Jet>, std::span<const Jet>,
                                    std::span<const Jet>, std::span<Jet>) const;
template void Model::Residuals<StateJet>(std::span<const StateJet>, std::span<const StateJet>,
                                         std::span<const StateJet>, std::span<const StateJet>,
                                         std::span<const StateJet>, std::span<const StateJet>,
                                         std::span<const StateJet>, std::span<StateJet>) const;
template void Model::Residual<double>(std::span<const double>, std::span<const double>, std::span<const double>,
                                      const double&, const double&, const double&, std::span<const double>,
                                      std::span<double>) const;
template void Model::Residual<Jet>(std::span<const Jet>, std::span<const Jet>, std::span<const Jet>, const Jet&,
                                   const Jet&, const Jet&, std::span<const Jet>, std::span<Jet>) const;
template void Model::Residual<StateJet>(std::span<const StateJet>, std::span<const StateJet>,
                                        std::span<const StateJet>, const StateJet&, const StateJet&, const StateJet&,
                                        std::span<const StateJet>, std::span<StateJet>) const;
template void Model::Outputs<double>(std::span<const double>, const double&, std::span<const double>,
                                     std::span<double>) const;
template void Model::Outputs<StateJet>(std::span<const StateJet>, const StateJet&, std::span<const StateJet>,
                                       std::span<StateJet>) const;
template void Model::Outputs<Jet>(std::span<const Jet>, const Jet&, std::span<const Jet>, std::span<Jet>) const;

}  // namespace strut::ident
