#include "strut/ident/experiment_data.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>
#include <optional>
#include <unsupported/Eigen/FFT>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

namespace strut::ident {
namespace {

// Runs of samples equal to `value` (exactly): lengths of every run.
std::vector<long> RunsAt(const std::vector<double>& x, double value) {
  std::vector<long> runs;
  long run = 0;
  for (double v : x) {
    if (v == value) {
      ++run;
    } else if (run > 0) {
      runs.push_back(run);
      run = 0;
    }
  }
  if (run > 0) runs.push_back(run);
  return runs;
}

// The sample-to-sample noise in codes of the channel's quantisation: a robust sd from the second
// differences (which a slowly varying signal hardly enters; their variance is 6 sd^2), over the
// smallest step between distinct values: very large for a channel stored without quantisation, 0 for
// a constant one.
double NoiseInCodes(const std::vector<double>& x) {
  if (x.size() < 8) return 0.0;
  std::vector<double> values(x);
  std::sort(values.begin(), values.end());
  double code = INFINITY;
  for (std::size_t i = 1; i < values.size(); ++i)
    if (values[i] > values[i - 1]) code = std::min(code, values[i] - values[i - 1]);
  if (!std::isfinite(code)) return 0.0;  // one value throughout
  std::vector<double> second;
  second.reserve(x.size());
  for (std::size_t i = 1; i + 1 < x.size(); ++i) second.push_back(std::abs(x[i + 1] - 2.0 * x[i] + x[i - 1]));
  const auto middle = second.begin() + static_cast<std::ptrdiff_t>(second.size() / 2);
  std::nth_element(second.begin(), middle, second.end());
  return *middle / (0.6745 * std::sqrt(6.0)) / code;
}

}  // namespace

PeriodicSeries PeriodicSeries::Fit(const Eigen::VectorXd& period, double frequency) {
  const int count = static_cast<int>(period.size());
  Eigen::FFT<double> fft;
  std::vector<std::complex<double>> spectrum;
  fft.fwd(spectrum, std::vector<double>(period.data(), period.data() + count));
  const int harmonics = (count - 1) / 2;  // below Nyquist
  std::vector<double> upper;
  for (int h = harmonics / 2 + 1; h <= harmonics; ++h) upper.push_back(std::abs(spectrum[h]));
  double threshold = 0.0;
  if (upper.size() >= 8) {
    std::nth_element(upper.begin(), upper.begin() + upper.size() / 2, upper.end());
    threshold = 6.0 * upper[upper.size() / 2];
  }
  PeriodicSeries series;
  series.frequency = frequency;
  series.coefficients.assign(harmonics + 1, 0.0);
  series.coefficients[0] = spectrum[0] / static_cast<double>(count);
  series.measured.resize(harmonics + 1);
  for (int h = 0; h <= harmonics; ++h) series.measured[h] = spectrum[h] / static_cast<double>(count);
  for (int h = 1; h <= harmonics; ++h) {
    if (std::abs(spectrum[h]) <= threshold) continue;
    series.coefficients[h] = spectrum[h] / static_cast<double>(count);
    ++series.kept;
  }
  return series;
}

Eigen::VectorXd PeriodicSeries::OnPhases(int count, int derivative) const {
  if (count < 1) throw std::invalid_argument("periodic series: no phases to evaluate at");
  std::vector<std::complex<double>> spectrum(count, 0.0);
  if (derivative == 0) spectrum[0] = coefficients[0] * static_cast<double>(count);
  const int harmonics = std::min<int>(static_cast<int>(coefficients.size()) - 1, (count - 1) / 2);
  for (int h = 1; h <= harmonics; ++h) {
    if (coefficients[h] == 0.0) continue;
    const std::complex<double> factor = std::pow(std::complex<double>(0.0, 2.0 * std::numbers::pi * frequency * h), derivative);
    spectrum[h] = coefficients[h] * factor * static_cast<double>(count);
    spectrum[count - h] = std::conj(spectrum[h]);
  }
  Eigen::FFT<double> fft;
  std::vector<double> values;
  fft.inv(values, spectrum);
  return Eigen::Map<const Eigen::VectorXd>(values.data(), count);
}

PeriodicInput PeriodicSeries::OnGrid(int n) const {
  // Zero-padded (or truncated) spectrum of length n: the series evaluated on the solver grid.
  std::vector<std::complex<double>> grid(n, 0.0);
  grid[0] = coefficients[0] * static_cast<double>(n);
  for (int h = 1; h < std::min<int>(coefficients.size(), (n - 1) / 2 + 1); ++h) {
    grid[h] = coefficients[h] * static_cast<double>(n);
    grid[n - h] = std::conj(grid[h]);
  }
  Eigen::FFT<double> fft;
  std::vector<double> values;
  fft.inv(values, grid);
  return PeriodicInput{frequency, values};
}

PeriodicInput PeriodicSeries::AtPhases(const std::vector<double>& phases) const {
  PeriodicInput in{frequency, std::vector<double>(phases.size(), coefficients[0].real()), phases};
  for (std::size_t h = 1; h < coefficients.size(); ++h) {
    if (coefficients[h] == 0.0) continue;
    for (std::size_t mu = 0; mu < phases.size(); ++mu)  // c_0 + sum 2 Re(c_h exp(i 2 pi h tau))
      in.values[mu] += 2.0 * (coefficients[h] * std::polar(1.0, 2.0 * std::numbers::pi * h * phases[mu])).real();
  }
  return in;
}

std::vector<double> ThinnedSamplePhases(const Eigen::VectorXd& velocity, int points,
                                        const std::vector<std::pair<const Eigen::VectorXd*, double>>& outputs) {
  const int count = static_cast<int>(velocity.size());
  const int widest = std::max(1, count / std::max(points, 1));
  std::vector<double> phases;
  if (widest < 2) {
    for (int i = 0; i < count; ++i) phases.push_back(static_cast<double>(i) / count);
    return phases;
  }
  const double peak = velocity.cwiseAbs().maxCoeff();
  // The step allowed at every sample (in samples, at most `widest`).
  std::vector<double> allowed(count, widest);
  for (int i = 0; i < count; ++i)
    if (peak > 0) allowed[i] = std::clamp(widest * std::abs(velocity[i]) / (0.5 * peak), 1.0, static_cast<double>(widest));
  for (const auto& [output, variance] : outputs) {
    if (!output || output->size() != count || !(variance > 0)) continue;
    const double limit = 4.0 * std::sqrt(6.0 * variance);  // the second difference of white noise: sd sqrt(6) s
    for (int i = 0; i < count; ++i) {
      const double second = (*output)[(i + 1) % count] - 2.0 * (*output)[i] + (*output)[(i + count - 1) % count];
      if (std::abs(second) > limit)
        for (int j = i - 4; j <= i + 4; ++j) allowed[(j % count + count) % count] = 1.0;
    }
  }
  // Growth by at most half a sample per sample, both ways round the period (twice: it is cyclic).
  for (int pass = 0; pass < 2; ++pass) {
    for (int i = 0; i < count; ++i) allowed[i] = std::min(allowed[i], allowed[(i + count - 1) % count] + 0.5);
    for (int i = count - 1; i >= 0; --i) allowed[i] = std::min(allowed[i], allowed[(i + 1) % count] + 0.5);
  }
  // Walk: from sample i the longest step no sample it spans forbids.
  for (int i = 0; i < count;) {
    phases.push_back(static_cast<double>(i) / count);
    int step = static_cast<int>(allowed[i]);
    for (int j = i + 1; j <= i + step; ++j) step = std::min(step, static_cast<int>(allowed[j % count]));
    i += std::max(1, step);
  }
  return phases;
}

std::vector<DataIssue> InspectChannel(const daq::Experiment& e, const daq::Channel& channel) {
  std::vector<DataIssue> issues;
  const std::vector<double>& x = channel.samples;
  const long count = static_cast<long>(x.size());
  if (count < 8) return issues;
  const auto add = [&](const char* kind, std::string detail) {
    issues.push_back({e.label, channel.name, kind, std::move(detail)});
  };

  // Dropout: a run of exact zeros in a channel that is not near zero (a lost connection reads 0).
  const auto zero_runs = RunsAt(x, 0.0);
  const long longest_zero = zero_runs.empty() ? 0 : *std::max_element(zero_runs.begin(), zero_runs.end());
  const bool dropout = longest_zero >= 5;
  if (dropout) {
    long total = 0;
    for (long r : zero_runs) total += r;
    add("dropout", fmt::format("{} samples read exactly 0 (longest run {})", total, longest_zero));
  }

  // Clipping: samples sitting exactly on the extreme value, in a run of 5 or more. A quantised sine
  // peak also repeats its top code where the noise spans less than a code or two, but for well under
  // 1.5 % of the samples; where the noise spans several codes no peak stays on one code for 5
  // samples, so there a run at the extreme is a saturated ADC however few samples it holds (a
  // load cell's range reached for a few tens of milliseconds at full compression).
  const double noise_codes = NoiseInCodes(x);
  for (const bool top : {true, false}) {
    const double extreme = top ? *std::max_element(x.begin(), x.end()) : *std::min_element(x.begin(), x.end());
    if (dropout && extreme == 0.0) continue;
    const auto runs = RunsAt(x, extreme);
    long at = 0, longest = 0;
    for (long r : runs) at += r, longest = std::max(longest, r);
    if (longest >= 5 && (at > 0.015 * count || noise_codes >= 2.0))
      add("clipped", fmt::format("{} samples ({:.1f} %) flat at the {} value {:.6g} {}", at, 100.0 * at / count,
                                 top ? "highest" : "lowest", extreme, channel.units));
  }

  // Dropouts and stuck values: long runs of one repeated value that is not an extreme.
  const double samples_per_period = e.frequency > 0 ? e.sample_rate / e.frequency : count;
  const long stuck_limit = std::max<long>(20, static_cast<long>(0.02 * samples_per_period));
  const double lo = *std::min_element(x.begin(), x.end()), hi = *std::max_element(x.begin(), x.end());
  long run = 1, worst = 0, worst_at = 0;
  double worst_value = 0.0;
  for (long i = 1; i <= count; ++i) {
    if (i < count && x[i] == x[i - 1]) {
      ++run;
      continue;
    }
    if (run > worst && x[i - 1] != lo && x[i - 1] != hi) worst = run, worst_at = i - run, worst_value = x[i - 1];
    run = 1;
  }
  if (worst >= stuck_limit && worst_value != 0.0)
    add("stuck",
        fmt::format("{} samples from index {} stuck at {:.6g} {}", worst, worst_at, worst_value, channel.units));

  // Outliers: far from the period-synchronous mean, in units of a robust spread.
  if (e.kind == daq::ExperimentKind::kPeriodic && e.periods >= 2 && e.frequency > 0) {
    const int n = std::max(16, static_cast<int>(std::min(samples_per_period, 4000.0)));
    try {
      const Eigen::VectorXd mean = PeriodSynchronousSamples(x, e.sample_rate, e.frequency, e.periods, n).rowwise().mean();
      std::vector<double> deviation(count);
      for (long i = 0; i < count; ++i) {
        const double phase = std::fmod(i / samples_per_period, 1.0) * n;
        const long j0 = static_cast<long>(std::floor(phase)) % n;
        const double w = phase - std::floor(phase);
        deviation[i] = x[i] - ((1 - w) * mean[j0] + w * mean[(j0 + 1) % n]);
      }
      std::vector<double> absolute(count);
      for (long i = 0; i < count; ++i) absolute[i] = std::abs(deviation[i]);
      std::nth_element(absolute.begin(), absolute.begin() + count / 2, absolute.end());
      const double robust_sigma = 1.4826 * absolute[count / 2];
      const double range = hi - lo;
      const double limit = std::max(10.0 * robust_sigma, 1e-6 * range);
      long outliers = 0, first = -1;
      for (long i = 0; i < count; ++i)
        if (std::abs(deviation[i]) > limit && range > 0) {
          if (first < 0) first = i;
          ++outliers;
        }
      // A few isolated spikes; a wholesale shift is a different defect (and shows elsewhere).
      if (outliers > 0 && outliers < 0.01 * count)
        add("outliers", fmt::format("{} samples more than {:.3g} {} (10 robust sigma) off the period mean, first at index {}",
                                    outliers, limit, channel.units, first));
    } catch (const std::invalid_argument&) {
      // Sizes are checked by the session validator; nothing to add here.
    }
  }
  return issues;
}

namespace {

// `thin`: slow experiments on ThinnedSamplePhases (the default grid under stroke input).
std::vector<ExperimentData> Prepare(const daq::Session& session, const std::string& input_channel, int n,
                                    std::vector<DataIssue>* issues, bool thin) {
  std::vector<ExperimentData> prepared;
  const std::string file = session.source_path.empty() ? "<memory>" : session.source_path;
  const std::vector<double> session_times = daq::ExperimentSessionTimes(session);
  for (std::size_t index = 0; index < session.experiments.size(); ++index) {
    const daq::Experiment& e = session.experiments[index];
    if (e.kind != daq::ExperimentKind::kPeriodic || e.status != "complete") {
      spdlog::info("{}: experiment '{}' skipped ({} {})", file, e.label, daq::ToString(e.kind), e.status);
      continue;
    }
    if (e.periods < 1)
      throw std::invalid_argument(fmt::format("{}: experiment '{}': no whole period recorded", file, e.label));
    ExperimentData d;
    d.session = file;
    d.label = e.label;
    d.group = e.group;
    d.frequency = e.frequency;
    d.amplitude = e.amplitude;
    d.static_position = e.static_position;
    d.periods = e.periods;
    d.sample_rate = e.sample_rate;
    d.session_time = session_times[index];
    // Whole samples per period: average the recorded samples themselves, phase by phase.
    const std::optional<long> whole_samples = daq::WholeSamplesPerPeriod(e.sample_rate, e.frequency, 4);
    const bool whole = whole_samples.has_value();
    const long native = whole_samples.value_or(0);
    // Not a whole number of samples a period: the record is resampled onto an equidistant grid; the
    // default keeps the 800 points it had before the thinned grid (200 would smear the friction's
    // switches of a slow experiment over a quarter as many phases).
    const int equidistant = thin && !whole ? std::max(n, kPaperGridPoints) : n;
    const bool thinned = thin && whole && native >= 2 * n;  // ThinnedSamplePhases below
    const int points = whole ? static_cast<int>(native) : equidistant;
    std::optional<PeriodicSeries> input_series;
    d.phases.resize(points);
    for (int i = 0; i < points; ++i) d.phases[i] = static_cast<double>(i) / points;
    for (const daq::Channel& c : e.channels) {
      if (issues && !daq::IsRecordingChannel(c)) {
        auto found = InspectChannel(e, c);
        issues->insert(issues->end(), found.begin(), found.end());
      }
      const std::vector<double> samples = c.name == "pressure" ? e.absolute_pressure() : c.samples;
      const Eigen::MatrixXd per_phase = PeriodSynchronousSamples(samples, e.sample_rate, e.frequency, e.periods, points);
      GridChannel g;
      g.mean = per_phase.rowwise().mean();
      if (c.name == "pressure" && c.reference == "gauge") g.reading_offset = daq::kGaugeReferencePa;
      if (e.periods >= 2) {
        g.noise_variance =
            (per_phase.colwise() - g.mean).squaredNorm() / (static_cast<double>(points) * (e.periods - 1));
        g.mean_noise_variance = g.noise_variance / e.periods;
      }
      if (c.name == input_channel) {
        const PeriodicSeries series = PeriodicSeries::Fit(g.mean, e.frequency);
        // The solver's grid holds every recorded sample phase: a whole multiple of the samples per
        // period, at least n; or, `thin`, the sample phases where the model may not be smooth and
        // fewer elsewhere (below). A slow experiment's friction jump at a reversal is as short as a
        // few samples; on a coarser equidistant grid the model smears it over a grid step (a 0.04 Hz
        // test with a near-stiction seal, theta10 = 2.7e4 s/m, left force noise ratios of 2.6-4.9 at
        // n = 800).
        const int grid = whole ? static_cast<int>(native * ((n + native - 1) / native)) : equidistant;
        if (!thinned) d.input = series.OnGrid(grid);
        input_series = series;
        // c_h = (1/count) sum x_i exp(-i 2 pi h i / count) of white noise of variance s^2 has
        // complex variance s^2 / count, so the mean's is s^2 / count and each of a_h = 2 Re c_h,
        // b_h = -2 Im c_h has 2 s^2 / count.
        for (std::size_t h = 0; h < series.coefficients.size(); ++h)
          if (h == 0 || series.coefficients[h] != 0.0) d.input_harmonics.push_back(static_cast<int>(h));
        d.input_measured = series.measured;
        d.input_mean_variance = g.mean_noise_variance / points;
        d.input_harmonic_variance = 2.0 * g.mean_noise_variance / points;
        spdlog::debug("{}: experiment '{}': {} input from {} harmonics", file, e.label, input_channel, series.kept);
      }
      d.channels[c.name] = std::move(g);
    }
    if (thinned && input_series) {
      // Every sample phase only where the model may not be smooth (docs/identification.md).
      std::vector<std::pair<const Eigen::VectorXd*, double>> outputs;
      for (const auto& [name, g] : d.channels)
        if (name != input_channel) outputs.emplace_back(&g.mean, g.mean_noise_variance);
      d.input = input_series->AtPhases(ThinnedSamplePhases(input_series->OnPhases(points, 1), n, outputs));
      spdlog::debug("{}: experiment '{}': grid of {} of its {} sample phases", file, e.label, d.input.values.size(),
                    points);
    }
    const auto input = d.channels.find(input_channel);
    if (input == d.channels.end())
      throw std::invalid_argument(
          fmt::format("{}: experiment '{}': no '{}' channel for the {} input", file, e.label, input_channel, input_channel));
    prepared.push_back(std::move(d));
  }
  return prepared;
}

}  // namespace

int DefaultGridPoints(Causality causality) { return causality == Causality::kStrokeInput ? 200 : kPaperGridPoints; }

Scheme DefaultScheme(Causality causality) {
  return causality == Causality::kStrokeInput ? Scheme::kCentral4 : Scheme::kBackward2;
}

int FitGridPoints(int n, std::optional<Scheme> scheme, Causality causality) {
  if (n > 0) return n;
  return scheme && *scheme != DefaultScheme(causality) ? kPaperGridPoints : 0;
}

std::vector<ExperimentData> PrepareExperiments(const daq::Session& session, Causality causality, int n,
                                               std::vector<DataIssue>* issues) {
  return Prepare(session, causality == Causality::kForceInput ? "force" : "stroke",
                 n > 0 ? n : DefaultGridPoints(causality), issues, n == 0 && causality == Causality::kStrokeInput);
}

std::vector<ExperimentData> PrepareExperiments(const daq::Session& session, const Model& model, int n,
                                               std::vector<DataIssue>* issues) {
  return Prepare(session, model.input_channel(), n > 0 ? n : DefaultGridPoints(model.causality()), issues,
                 n == 0 && model.causality() == Causality::kStrokeInput);
}

}  // namespace strut::ident
