#include "clod_haptics/core/latency_histogram.h"

#include <algorithm>
#include <cmath>

namespace clod_haptics {

int LatencyHistogram::binOf(std::int64_t ns) noexcept {
  if (ns < 0) ns = 0;
  const std::int64_t us = ns / 1000;
  if (us < 1000) return static_cast<int>(us);
  if (us < 100000) return kFine + static_cast<int>((us - 1000) / 100);
  if (us < 10000000) return kFine + kMiddle + static_cast<int>((us - 100000) / 10000);
  return kBins - 1;
}

double LatencyHistogram::upperEdgeUs(int bin) noexcept {
  if (bin < kFine) return bin + 1.0;
  if (bin < kFine + kMiddle) return 1000.0 + (bin - kFine + 1) * 100.0;
  return 100000.0 + (bin - kFine - kMiddle + 1) * 10000.0;
}

void LatencyHistogram::record(std::int64_t ns) noexcept {
  if (ns < 0) ns = 0;
  bins_[static_cast<std::size_t>(binOf(ns))].fetch_add(1, std::memory_order_relaxed);
  count_.fetch_add(1, std::memory_order_relaxed);
  // One writer: a plain compare then store is enough for the maxima.
  if (ns > maxNs_.load(std::memory_order_relaxed)) maxNs_.store(ns, std::memory_order_relaxed);
  std::int64_t period = periodMaxNs_.load(std::memory_order_relaxed);
  while (ns > period && !periodMaxNs_.compare_exchange_weak(period, ns, std::memory_order_relaxed)) {
  }
}

double LatencyHistogram::percentileUs(double q) const noexcept {
  std::uint64_t total = 0;
  for (const auto& b : bins_) total += b.load(std::memory_order_relaxed);
  if (total == 0 || !(q > 0.0)) return 0.0;
  // The rank of the q-th percentile (nearest rank): the smallest sample with at least q% at or below it.
  const auto rank = static_cast<std::uint64_t>(std::ceil(std::min(q, 100.0) / 100.0 * static_cast<double>(total)));
  std::uint64_t seen = 0;
  for (int i = 0; i < kBins; ++i) {
    seen += bins_[static_cast<std::size_t>(i)].load(std::memory_order_relaxed);
    if (seen >= rank) return i == kBins - 1 ? maxUs() : std::min(upperEdgeUs(i), maxUs());  // both bound it
  }
  return maxUs();
}

}  // namespace clod_haptics
