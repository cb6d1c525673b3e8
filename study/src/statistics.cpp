#include "strut/study/statistics.h"

#include <algorithm>
#include <cmath>

namespace strut::study {

double Median(std::vector<double> values) {
  if (values.empty()) return NAN;
  std::sort(values.begin(), values.end());
  const std::size_t half = values.size() / 2;
  return values.size() % 2 ? values[half] : 0.5 * (values[half - 1] + values[half]);
}

std::pair<double, double> Wilson(long k, long total) {
  if (total <= 0) return {NAN, NAN};
  const double z = kZ95, p = static_cast<double>(k) / total, nn = static_cast<double>(total);
  const double centre = (p + z * z / (2 * nn)) / (1 + z * z / nn);
  const double half = z / (1 + z * z / nn) * std::sqrt(p * (1 - p) / nn + z * z / (4 * nn * nn));
  return {centre - half, centre + half};
}

std::pair<double, double> BinomialRange(long total, double p) {
  double cumulative = 0.0;
  long lo = -1, hi = total;
  for (long k = 0; k <= total; ++k) {
    cumulative += std::exp(std::lgamma(total + 1.0) - std::lgamma(k + 1.0) - std::lgamma(total - k + 1.0) +
                           k * std::log(p) + (total - k) * std::log1p(-p));
    if (lo < 0 && cumulative >= 0.025) lo = k;
    if (cumulative >= 0.975) {
      hi = k;
      break;
    }
  }
  return {static_cast<double>(lo) / total, static_cast<double>(hi) / total};
}

ZCoverage SummariseZ(const std::vector<double>& z, double threshold) {
  ZCoverage c;
  c.total = static_cast<long>(z.size());
  const double n = static_cast<double>(z.size());
  double var = 0.0;
  for (double v : z) {
    c.inside += std::abs(v) <= threshold;
    c.mean_z += v / n;
  }
  for (double v : z) var += (v - c.mean_z) * (v - c.mean_z) / std::max(1.0, n - 1);
  c.sd_z = std::sqrt(var);
  c.wilson95 = Wilson(c.inside, c.total);
  return c;
}

}  // namespace strut::study
