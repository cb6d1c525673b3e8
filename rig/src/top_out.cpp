#include "strut/rig/top_out.h"

#include <spdlog/fmt/fmt.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace strut::rig {

bool TopOutOptions::IsValid(std::string* error) const {
  auto fail = [&](std::string m) {
    if (error) *error = std::move(m);
    return false;
  };
  if (!std::isfinite(from) || !std::isfinite(to) || !(from > to))
    return fail(fmt::format("top-out reference: the search runs from {} m down to {} m: give from > to", from, to));
  if (!(rate > 0.0) || !std::isfinite(rate)) return fail(fmt::format("top-out reference: rate {} m/s must be positive", rate));
  if (!(force_drop > 0.0) || !std::isfinite(force_drop))
    return fail(fmt::format("top-out reference: force limit {} N must be positive", force_drop));
  if (persistence < 1) return fail(fmt::format("top-out reference: persistence {} must be at least 1", persistence));
  if (!(settle >= 0.0) || !(settle < from - to))
    return fail(fmt::format("top-out reference: settle {} m must be within 0 .. the search's {} m", settle, from - to));
  if (!(window > 0.0)) return fail(fmt::format("top-out reference: window {} m must be positive", window));
  if (!(gain_sd >= 0.0) || !std::isfinite(gain_sd))
    return fail(fmt::format("top-out reference: gain sd {} must not be negative", gain_sd));
  return true;
}

std::vector<std::string> CheckTopOut(const TopOutOptions& o, const SafetyConfig& c) {
  std::vector<std::string> refusals;
  const auto refuse = [&](std::string what) { refusals.push_back("top-out reference: " + what); };
  std::string error;
  if (!o.IsValid(&error)) {
    refusals.push_back(error);
    return refusals;
  }
  const double lowest = std::max(c.stroke.enabled ? c.stroke.lower : -1e300, c.controller.stroke_min);
  const double highest = std::min(c.stroke.enabled ? c.stroke.upper : 1e300, c.controller.stroke_max);
  if (o.to < lowest || o.from > highest)
    refuse(fmt::format("the search {:.4g} .. {:.4g} m leaves the stroke limit {:.4g} .. {:.4g} m (give --top-out-to "
                       "inside it, or --no-top-out)",
                       o.to, o.from, lowest, highest));
  if (o.rate > c.actuator.max_velocity)
    refuse(fmt::format("rate {:.4g} m/s exceeds the velocity limit {:.4g} m/s", o.rate, c.actuator.max_velocity));
  // Top-out pulls the axle toward tension: from a force of zero at the stop (an unloaded strut
  // rests there), the move's force limit must stay inside the limits' tension side.
  const double tension = std::max(c.force.enabled ? c.force.lower : -1e300, c.controller.force_min);
  if (-o.force_drop <= tension)
    refuse(fmt::format("its force limit of {:.4g} N below the trend reaches the force limit {:.4g} N", o.force_drop,
                       tension));
  return refusals;
}

bool TopOutDetector::Add(double stroke, double force) {
  if (found_) return true;
  if (!first_stroke_) first_stroke_ = stroke;
  const double u = stroke - *first_stroke_;  // negative as the search goes on
  if (-u < options_.settle) return false;
  // The trend needs as much travel again before it is trusted (and two dozen samples).
  const double span = n_ > 0 ? (sy_ / n_ - u) : 0.0;
  if (n_ >= 24 && -u >= 2 * options_.settle && span > 0) {
    const double det = n_ * syy_ - sy_ * sy_;
    const double b = det > 0 ? (n_ * syf_ - sy_ * sf_) / det : 0.0;
    const double a = (sf_ - b * sy_) / n_;
    const double shortfall = a + b * u - force;
    measure_ = std::max(0.0, shortfall / options_.force_drop);
    if (shortfall > options_.force_drop) {
      if (below_ == 0) candidate_ = stroke;
      if (++below_ >= options_.persistence) {
        found_ = true;
        contact_stroke_ = candidate_;
      }
      return found_;
    }
  }
  below_ = 0;
  n_ += 1;
  sy_ += u;
  sf_ += force;
  syy_ += u * u;
  syf_ += u * force;
  return false;
}

namespace {

// Sums over the samples after a candidate contact time (suffix sums of 1, t, t^2, F, t F).
struct Suffix {
  std::vector<double> n, t, tt, f, tf;
  explicit Suffix(std::span<const double> time, std::span<const double> force) {
    const std::size_t m = time.size();
    n.assign(m + 1, 0.0), t = tt = f = tf = n;
    for (std::size_t i = m; i-- > 0;) {
      n[i] = n[i + 1] + 1;
      t[i] = t[i + 1] + time[i];
      tt[i] = tt[i + 1] + time[i] * time[i];
      f[i] = f[i + 1] + force[i];
      tf[i] = tf[i + 1] + time[i] * force[i];
    }
  }
};

struct Hinge {
  double rss = INFINITY;
  Eigen::Vector3d beta = Eigen::Vector3d::Zero();  // a, b, c
};

// Least squares of F = a + b t + c max(0, t - tc) for a contact time tc with the samples from
// index `first` on after it.
Hinge FitHinge(const Suffix& s, std::size_t first, double tc) {
  const double n = s.n[0], st = s.t[0], stt = s.tt[0], sf = s.f[0], stf = s.tf[0];
  const double hn = s.n[first], ht = s.t[first], htt = s.tt[first], hf = s.f[first], htf = s.tf[first];
  const double sh = ht - tc * hn, shh = htt - 2 * tc * ht + tc * tc * hn, sht = htt - tc * ht, shf = htf - tc * hf;
  Eigen::Matrix3d a;
  a << n, st, sh, st, stt, sht, sh, sht, shh;
  const Eigen::Vector3d rhs(sf, stf, shf);
  Hinge h;
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(a);
  if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-14)) return h;
  h.beta = ldlt.solve(rhs);
  h.rss = -h.beta.dot(rhs);  // + sum F^2, the same for every tc: left out
  return h;
}

}  // namespace

TopOutFit FitTopOut(std::span<const double> time, std::span<const double> stroke, std::span<const double> force,
                    double contact, double resolution, const TopOutOptions& options) {
  if (time.size() != stroke.size() || time.size() != force.size())
    throw std::invalid_argument("top-out fit: time, stroke and force differ in length");
  // The window: from the first sample within `window` above the contact on.
  std::size_t begin = 0;
  while (begin < stroke.size() && stroke[begin] > contact + options.window) ++begin;
  const std::size_t m = stroke.size() - begin;
  constexpr std::size_t kMinSide = 10;
  if (m < 4 * kMinSide)
    throw std::invalid_argument(fmt::format("top-out fit: {} samples within {:.1f} mm above the contact, too few", m,
                                            options.window * 1e3));
  std::vector<double> t(m), f(m), y(m);
  const double t0 = time[begin];
  for (std::size_t i = 0; i < m; ++i) t[i] = time[begin + i] - t0, f[i] = force[begin + i], y[i] = stroke[begin + i];
  const Suffix s(t, f);

  // Profile over the contact time: at the samples, then finer between the best one's neighbours.
  std::size_t best = kMinSide;
  double best_rss = INFINITY;
  for (std::size_t j = kMinSide; j + kMinSide < m; ++j) {
    const Hinge h = FitHinge(s, j, t[j]);
    if (h.rss < best_rss) best_rss = h.rss, best = j;
  }
  double tc = t[best];
  {
    constexpr int kSub = 20;
    for (std::size_t j = best - 1; j <= best; ++j) {  // tc in (t[j], t[j+1]]: the samples from j+1 are after it
      for (int k = 1; k <= kSub; ++k) {
        const double c = t[j] + (t[j + 1] - t[j]) * k / kSub;
        const Hinge h = FitHinge(s, j + 1, c);
        if (h.rss < best_rss) best_rss = h.rss, tc = c;
      }
    }
  }
  std::size_t after = 0;
  while (after < m && t[after] <= tc) ++after;
  const Hinge h = FitHinge(s, after, tc);
  const double a = h.beta[0], b = h.beta[1], c = h.beta[2];

  // Residual variances before and after the contact apart (the stop adds the actuator's and the
  // reading's noise times its stiffness), then the linearised covariance of (a, b, c, tc).
  double rss_pre = 0, rss_post = 0, rss = 0;
  for (std::size_t i = 0; i < m; ++i) {
    const double r = f[i] - (a + b * t[i] + c * std::max(0.0, t[i] - tc));
    (i < after ? rss_pre : rss_post) += r * r;
    rss += r * r;
  }
  const long n_pre = static_cast<long>(after), n_post = static_cast<long>(m - after);
  if (n_pre < static_cast<long>(kMinSide) || n_post < static_cast<long>(kMinSide))
    throw std::invalid_argument(fmt::format("top-out fit: {} samples before the contact and {} after: too few", n_pre,
                                            n_post));
  const double v_pre = rss_pre / static_cast<double>(n_pre - 2), v_post = rss_post / static_cast<double>(n_post - 2);
  Eigen::Matrix4d info = Eigen::Matrix4d::Zero();
  for (std::size_t i = 0; i < m; ++i) {
    const bool in = i >= after;
    const Eigen::Vector4d j(1.0, t[i], in ? t[i] - tc : 0.0, in ? -c : 0.0);
    info += j * j.transpose() / (in ? v_post : v_pre);
  }
  const Eigen::Matrix4d cov = info.inverse();
  const double sd_tc = std::sqrt(std::max(0.0, cov(3, 3))), sd_c = std::sqrt(std::max(0.0, cov(2, 2)));
  if (!(c < 0.0) || !(-c > 10.0 * sd_c))
    throw std::invalid_argument(fmt::format("top-out fit: the force does not fall faster after the contact "
                                            "({:.4g} +- {:.2g} N/s more): no stop in the samples",
                                            c, sd_c));

  // The stroke line over the samples before the contact, at the contact time.
  double mt = 0, my = 0;
  for (std::size_t i = 0; i < after; ++i) mt += t[i] - tc, my += y[i];
  mt /= static_cast<double>(n_pre), my /= static_cast<double>(n_pre);
  double stt = 0, sty = 0;
  for (std::size_t i = 0; i < after; ++i) stt += (t[i] - tc - mt) * (t[i] - tc - mt), sty += (t[i] - tc - mt) * (y[i] - my);
  const double rate = sty / stt, at_contact = my - rate * mt;
  double ryy = 0;
  for (std::size_t i = 0; i < after; ++i) {
    const double r = y[i] - (at_contact + rate * (t[i] - tc));
    ryy += r * r;
  }
  const double vy = ryy / static_cast<double>(n_pre - 2);
  const double var_line = vy * (1.0 / static_cast<double>(n_pre) + mt * mt / stt);

  TopOutFit fit;
  fit.zero = at_contact;
  fit.fit_sd = std::sqrt(var_line + rate * rate * sd_tc * sd_tc);
  const double gain = options.gain_sd * fit.zero;
  fit.sd = std::sqrt(fit.fit_sd * fit.fit_sd + resolution * resolution / 12.0 + gain * gain);
  fit.contact_time = tc + t0 - time[0];
  fit.stroke_rate = rate;
  fit.stiffness = rate != 0.0 ? c / rate : 0.0;
  fit.residual_rms = std::sqrt(rss / static_cast<double>(m));
  fit.samples = static_cast<long>(m);
  fit.in_contact = n_post;
  return fit;
}

}  // namespace strut::rig
