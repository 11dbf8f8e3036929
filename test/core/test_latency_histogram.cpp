// LatencyHistogram against the percentiles of the same samples sorted (nearest rank).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "clod_haptics/core/latency_histogram.h"

namespace {

using clod_haptics::LatencyHistogram;

// Nearest-rank percentile of sorted samples, in microseconds.
double reference(const std::vector<std::int64_t>& sorted, double q) {
  const auto rank = static_cast<std::size_t>(std::ceil(q / 100.0 * static_cast<double>(sorted.size())));
  return static_cast<double>(sorted[std::max<std::size_t>(rank, 1) - 1]) * 1e-3;
}

// The bin width at a value: a percentile is never below the truth and at most one bin above it.
double binWidthUs(double us) { return us < 1000.0 ? 1.0 : us < 100000.0 ? 100.0 : 10000.0; }

TEST(LatencyHistogram, PercentilesBoundTheSortedSamplesFromAboveWithinOneBin) {
  std::mt19937_64 rng(7);
  // A haptic-like stream: most answers in microseconds, a tail of stalls up to seconds.
  std::lognormal_distribution<double> fast(std::log(3000.0), 0.6);
  std::uniform_real_distribution<double> stall(1e6, 3e9);
  std::bernoulli_distribution isStall(0.004);
  LatencyHistogram h;
  std::vector<std::int64_t> samples;
  for (int i = 0; i < 200000; ++i) {
    const auto ns = static_cast<std::int64_t>(isStall(rng) ? stall(rng) : fast(rng));
    samples.push_back(ns);
    h.record(ns);
  }
  std::sort(samples.begin(), samples.end());
  EXPECT_EQ(h.count(), samples.size());
  for (double q : {1.0, 50.0, 90.0, 99.0, 99.5, 99.9, 99.99, 100.0}) {
    const double truth = reference(samples, q);
    const double got = h.percentileUs(q);
    EXPECT_GE(got, truth) << "p" << q;
    EXPECT_LE(got, truth + binWidthUs(truth) + 1e-9) << "p" << q;
  }
  EXPECT_DOUBLE_EQ(h.maxUs(), static_cast<double>(samples.back()) * 1e-3);
}

TEST(LatencyHistogram, OverflowAndNegativeSamples) {
  LatencyHistogram h;
  EXPECT_EQ(h.percentileUs(99.0), 0.0);
  EXPECT_EQ(h.maxUs(), 0.0);
  h.record(-5);                       // a clock step backwards: counted as 0
  h.record(20'000'000'000);           // 20 s: beyond the last bin
  EXPECT_EQ(h.count(), 2u);
  EXPECT_LE(h.percentileUs(50.0), 1.0);
  EXPECT_DOUBLE_EQ(h.percentileUs(100.0), 20e6);  // the overflow bin answers the exact maximum
}

TEST(LatencyHistogram, PeriodMaximumRestartsEachPeriod) {
  LatencyHistogram h;
  h.record(5000);
  h.record(90000);
  EXPECT_DOUBLE_EQ(h.takePeriodMaxUs(), 90.0);
  EXPECT_DOUBLE_EQ(h.takePeriodMaxUs(), 0.0);
  h.record(7000);
  EXPECT_DOUBLE_EQ(h.takePeriodMaxUs(), 7.0);
  EXPECT_DOUBLE_EQ(h.maxUs(), 90.0);  // the overall maximum stays
}

}  // namespace
