// The study library's pure pieces against independent references: the Wilson interval and the
// binomial range against values computed separately (Python, exact binomial sums), the median,
// the z coverage counting, the detection size and the bins of the confusion study on hand-made
// units, and the lot's defect rotation.
#include <gtest/gtest.h>

#include <cmath>

#include "strut/study/confusion.h"
#include "strut/study/lot.h"
#include "strut/study/statistics.h"

namespace strut::study {
namespace {

TEST(StudyStatistics, WilsonIntervalMatchesTheClosedFormComputedSeparately) {
  // 8 of 10: (0.490162, 0.943318); 95 of 100: (0.888250, 0.978456); 0 of 20: (0, 0.161125).
  const auto a = Wilson(8, 10);
  EXPECT_NEAR(a.first, 0.4901625, 1e-6);
  EXPECT_NEAR(a.second, 0.9433178, 1e-6);
  const auto b = Wilson(95, 100);
  EXPECT_NEAR(b.first, 0.8882495, 1e-6);
  EXPECT_NEAR(b.second, 0.9784563, 1e-6);
  const auto c = Wilson(0, 20);
  EXPECT_NEAR(c.first, 0.0, 1e-12);
  EXPECT_NEAR(c.second, 0.1611252, 1e-6);
  EXPECT_TRUE(std::isnan(Wilson(0, 0).first));
}

TEST(StudyStatistics, BinomialRangeIsTheExactQuantiles) {
  // The 2.5 % and 97.5 % quantiles of Binomial(N, 0.95) over N, from exact sums of C(N, k) p^k q^(N-k).
  EXPECT_EQ(BinomialRange(100, 0.95), std::make_pair(0.90, 0.99));
  EXPECT_EQ(BinomialRange(200, 0.95), std::make_pair(0.92, 0.98));
  EXPECT_EQ(BinomialRange(20, 0.95), std::make_pair(0.85, 1.0));
}

TEST(StudyStatistics, MedianOfOddAndEvenCounts) {
  EXPECT_DOUBLE_EQ(Median({3.0, 1.0, 2.0}), 2.0);
  EXPECT_DOUBLE_EQ(Median({4.0, 1.0, 3.0, 2.0}), 2.5);  // the mean of the middle two
  EXPECT_DOUBLE_EQ(Median({7.0}), 7.0);
  EXPECT_TRUE(std::isnan(Median({})));
}

TEST(StudyStatistics, CoverageCountsTheZInsideTheThreshold) {
  // Five realisations, two outside the 95 % interval (one just beyond 1.96, one far), one on its edge.
  const std::vector<double> z = {0.5, -1.0, 1.97, -3.0, kZ95};
  const ZCoverage c = SummariseZ(z);
  EXPECT_EQ(c.inside, 3);
  EXPECT_EQ(c.total, 5);
  EXPECT_DOUBLE_EQ(c.fraction(), 0.6);
  const double mean = (0.5 - 1.0 + 1.97 - 3.0 + kZ95) / 5;
  double ss = 0.0;
  for (double v : z) ss += (v - mean) * (v - mean);
  EXPECT_NEAR(c.mean_z, mean, 1e-15);
  EXPECT_NEAR(c.sd_z, std::sqrt(ss / 4), 1e-14);
  EXPECT_EQ(c.wilson95, Wilson(3, 5));
  EXPECT_EQ(SummariseZ(z, 1.0).inside, 2);  // another threshold
}

TEST(StudyConfusion, DetectionSizeIsWhereNinetyFivePercentAreRightAbove) {
  // 30 units at sizes 1..30: wrong below 11, right from 11 on except 20. Above 11: 19 of 20 right
  // (95 %); above 10: 19 of 21 (90 %).
  std::vector<std::pair<double, bool>> units;
  for (int s = 30; s >= 1; --s) units.emplace_back(s, s >= 11 && s != 20);
  EXPECT_DOUBLE_EQ(DetectionSize(units), 11.0);
  // Fewer than 10 units above any size: not reached.
  std::vector<std::pair<double, bool>> few(9, {1.0, true});
  EXPECT_TRUE(std::isnan(DetectionSize(few)));
}

TEST(StudyConfusion, BinsAreFifthsOfTheSortedUnits) {
  std::vector<std::pair<double, bool>> units;
  for (int s = 10; s >= 1; --s) units.emplace_back(s, s % 2 == 0);
  const std::vector<MeasureBin> bins = Bins(units);
  ASSERT_EQ(bins.size(), 5u);
  for (std::size_t b = 0; b < 5; ++b) {
    EXPECT_DOUBLE_EQ(bins[b].low, 2.0 * b + 1);
    EXPECT_DOUBLE_EQ(bins[b].high, 2.0 * b + 2);
    EXPECT_EQ(bins[b].right, 1);
    EXPECT_EQ(bins[b].count, 2);
  }
  EXPECT_EQ(Bins({{1.0, true}, {2.0, false}}).size(), 2u);  // three bins would be empty
}

TEST(StudyLot, DefectsTakeTurnsInTheirTenths) {
  LotOptions o;
  o.defect_tenths = 3;
  // Units 0, 1, 2 of every ten are defective, the kinds in turn; 3..9 good.
  EXPECT_EQ(o.KindOf(0), Defect::kUnderCharge);
  EXPECT_EQ(o.KindOf(1), Defect::kExcessFriction);
  EXPECT_EQ(o.KindOf(2), Defect::kOilOverfill);
  EXPECT_EQ(o.KindOf(3), Defect::kNone);
  EXPECT_EQ(o.KindOf(9), Defect::kNone);
  EXPECT_EQ(o.KindOf(10), Defect::kLowOil);
  EXPECT_EQ(o.KindOf(12), Defect::kLeakingSeal);
  EXPECT_EQ(o.KindOf(20), Defect::kUnderCharge);  // the sixth defect came before: the turn starts again
  o.defect_tenths = 0;
  EXPECT_EQ(o.KindOf(0), Defect::kNone);
}

}  // namespace
}  // namespace strut::study
