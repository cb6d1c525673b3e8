#include "strut/study/oscillator.h"

#include <Eigen/Dense>
#include <cmath>
#include <complex>
#include <fmt/format.h>
#include <numbers>
#include <stdexcept>
#include <unsupported/Eigen/FFT>

namespace strut::study {

using namespace strut::ident;

OscillatorPredictor::OscillatorPredictor(Model model, PeriodicSolverOptions options)
    : model_(model), solver_(std::move(model), options) {}

PeriodicSolution OscillatorPredictor::Solve(const PeriodicInput& input, std::span<const double> theta,
                                            const PeriodicSolution* warm_start) {
  const int n = static_cast<int>(input.values.size());
  if (warm_start || !model_.has_term("linear-oscillator") || model_.unknown_count() != 1 ||
      model_.causality() != Causality::kForceInput || n < 4 || !(input.frequency > 0))
    return solver_.Solve(input, theta, warm_start);
  const ParameterSet& p = model_.defaults();
  const double m = theta[p.position_of_index(50)], d = theta[p.position_of_index(51)],
               k = theta[p.position_of_index(52)];
  const int offset = p.position_of_index(55);
  Eigen::FFT<double> fft;
  std::vector<std::complex<double>> spectrum;
  fft.fwd(spectrum, input.values);
  if (offset >= 0) spectrum[0] -= theta[offset] * static_cast<double>(n);
  for (int h = 0; h <= n / 2; ++h) {
    const double w = 2.0 * std::numbers::pi * input.frequency * h;
    const std::complex<double> dynamic(k - m * w * w, d * w);
    spectrum[h] = std::abs(dynamic) > 0 ? spectrum[h] / dynamic : 0.0;
    if (h > 0 && h < n - h) spectrum[n - h] = std::conj(spectrum[h]);
  }
  std::vector<double> y;
  fft.inv(y, spectrum);
  PeriodicSolution guess;
  guess.n = n;
  guess.frequency = input.frequency;
  guess.unknowns = Eigen::Map<const Eigen::RowVectorXd>(y.data(), n);
  if (!guess.unknowns.allFinite()) return solver_.Solve(input, theta, nullptr);
  return solver_.Solve(input, theta, &guess);
}

std::vector<Eigen::MatrixXd> OscillatorPredictor::OutputSensitivities(const PeriodicSolution& solution,
                                                                      std::span<const double> theta,
                                                                      std::span<const int> parameters, bool exact) {
  return solver_.OutputSensitivities(solution, theta, parameters, exact);
}

std::vector<double> BandLimitedUpsample(std::span<const double> samples, int factor) {
  const int count = static_cast<int>(samples.size());
  if (count < 2 || factor < 1) throw std::invalid_argument("band-limited upsampling needs 2 samples and factor >= 1");
  Eigen::FFT<double> fft;
  std::vector<std::complex<double>> spectrum;
  fft.fwd(spectrum, std::vector<double>(samples.begin(), samples.end()));
  const long fine = static_cast<long>(count) * factor;
  std::vector<std::complex<double>> padded(fine, 0.0);
  for (int k = 0; k <= (count - 1) / 2; ++k) {
    padded[k] = spectrum[k] * static_cast<double>(factor);
    if (k > 0) padded[fine - k] = spectrum[count - k] * static_cast<double>(factor);
  }
  if (count % 2 == 0) {  // the Nyquist bin, split between +- count/2 so the result stays real
    padded[count / 2] = 0.5 * spectrum[count / 2] * static_cast<double>(factor);
    padded[fine - count / 2] = padded[count / 2];
  }
  std::vector<double> values;
  fft.inv(values, padded);
  return values;
}

namespace {

// Smallest 2^a 3^b 5^c >= n (fast FFT lengths).
long FftLength(long n) {
  for (long m = n;; ++m) {
    long r = m;
    for (long p : {2L, 3L, 5L})
      while (r % p == 0) r /= p;
    if (r == 1) return m;
  }
}

}  // namespace

std::vector<double> BandLimitedRecord(std::span<const double> samples, int factor) {
  const long count = static_cast<long>(samples.size());
  if (count < 2) throw std::invalid_argument("band-limited record: needs 2 samples");
  const long period = FftLength(count + std::max(256L, count / 64));
  std::vector<double> extended(samples.begin(), samples.end());
  extended.resize(period);
  for (long i = count; i < period; ++i) {
    const double w = 0.5 - 0.5 * std::cos(std::numbers::pi * (i - count + 1) / (period - count + 1));
    extended[i] = (1.0 - w) * samples.back() + w * samples.front();
  }
  return BandLimitedUpsample(extended, factor);
}

std::vector<double> SimulateFromRest(const Model& model, std::span<const double> theta, std::span<const double> input,
                                     double sample_rate, int substeps) {
  if (model.causality() != Causality::kForceInput || model.unknown_count() != 1)
    throw std::invalid_argument(fmt::format(
        "SimulateFromRest integrates force-input models without states; '{}' ({} input) is not one (use "
        "sim::TransientSimulator)",
        model.composition(), ToString(model.causality())));
  if (static_cast<int>(theta.size()) != model.parameter_count())
    throw std::invalid_argument(
        fmt::format("SimulateFromRest: {} parameter values for a model with {}", theta.size(), model.parameter_count()));
  if (input.size() < 2 || !(sample_rate > 0) || substeps < 1)
    throw std::invalid_argument("SimulateFromRest: needs 2 input samples, a positive rate and substeps >= 1");
  for (double u : input)
    if (!std::isfinite(u)) throw std::invalid_argument("SimulateFromRest: the input has non-finite samples");

  // The input on 2 * substeps points per sample (RK4 needs the half steps), band-limited.
  const long count = static_cast<long>(input.size());
  const int fine = 2 * substeps;
  const std::vector<double> u = BandLimitedRecord(input, fine);

  // y'' from the residual, which is affine in y'' (checked): r(a) = r0 + (r1 - r0) a.
  std::vector<double> x(1), xd(1), xdd(1), r(1);
  const auto residual = [&](double y, double v, double a, double uu) {
    x[0] = y, xd[0] = v, xdd[0] = a;
    model.Residual<double>(x, xd, xdd, uu, 0.0, 0.0, theta, r);
    return r[0];
  };
  const auto accel = [&](double y, double v, double uu) {
    const double r0 = residual(y, v, 0.0, uu), r1 = residual(y, v, 1.0, uu);
    return -r0 / (r1 - r0);
  };
  const std::vector<double> rest = model.StaticEquilibrium(input.front(), theta);
  {
    const double r0 = residual(rest[0], 0.1, 0.0, input.front()), r1 = residual(rest[0], 0.1, 1.0, input.front()),
                 r2 = residual(rest[0], 0.1, 2.0, input.front());
    if (std::abs(r2 - 2.0 * r1 + r0) > 1e-9 * (std::abs(r0) + std::abs(r1) + std::abs(r2)) || r1 == r0)
      throw std::invalid_argument(
          fmt::format("SimulateFromRest: model '{}' is not affine in the output acceleration", model.composition()));
  }
  const double h = 1.0 / (sample_rate * substeps);
  double y = rest[0], v = 0.0;
  std::vector<double> output(count), out(model.output_channels().size());
  const auto record = [&](long i) {
    x[0] = y;
    model.Outputs<double>(x, input[i], theta, out);
    output[i] = out[0];
  };
  record(0);
  for (long i = 0; i + 1 < count; ++i) {
    for (int k = 0; k < substeps; ++k) {
      const long at = i * fine + 2 * k;
      const double u0 = u[at], uh = u[at + 1], u1 = u[at + 2];
      const double k1y = v, k1v = accel(y, v, u0);
      const double k2y = v + 0.5 * h * k1v, k2v = accel(y + 0.5 * h * k1y, k2y, uh);
      const double k3y = v + 0.5 * h * k2v, k3v = accel(y + 0.5 * h * k2y, k3y, uh);
      const double k4y = v + h * k3v, k4v = accel(y + h * k3y, k4y, u1);
      y += h / 6.0 * (k1y + 2.0 * k2y + 2.0 * k3y + k4y);
      v += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
    }
    if (!std::isfinite(y) || !std::isfinite(v))
      throw std::runtime_error(fmt::format("SimulateFromRest: model '{}' diverged at sample {} (t = {:.6g} s)",
                                           model.composition(), i + 1, (i + 1) / sample_rate));
    record(i + 1);
  }
  return output;
}

}  // namespace strut::study
