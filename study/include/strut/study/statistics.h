// The statistics the studies report: medians, binomial intervals for coverage fractions, and the
// summary of z = (estimate - truth) / sd over realisations.
#pragma once

#include <map>
#include <string>
#include <utility>
#include <vector>

namespace strut::study {

//! The median (the mean of the middle two for an even count); NaN for none.
double Median(std::vector<double> values);

//! Wilson score interval (95 %) of a binomial fraction k / total; NaN for no trials.
std::pair<double, double> Wilson(long k, long total);

//! Central 95 % range of k / N for k ~ Binomial(N, p): the 2.5 % and 97.5 % quantiles over N. What
//! a calibrated interval's coverage fraction falls in with 95 % probability.
std::pair<double, double> BinomialRange(long total, double p);

//! Two-sided 95 % normal quantile.
inline constexpr double kZ95 = 1.959963984540054;

//! How often intervals held the truth, from the z of each realisation.
struct ZCoverage {
  long inside = 0;  //!< realisations with |z| <= the threshold
  long total = 0;
  double mean_z = 0.0;
  double sd_z = 0.0;  //!< sample sd (n - 1); 0 for one realisation
  std::pair<double, double> wilson95;  //!< of inside / total
  double fraction() const { return static_cast<double>(inside) / total; }
};

//! The coverage of `z` at |z| <= `threshold` (kZ95: the 95 % interval).
ZCoverage SummariseZ(const std::vector<double>& z, double threshold = kZ95);

}  // namespace strut::study
