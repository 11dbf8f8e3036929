#pragma once

#include <array>
#include <atomic>
#include <cstdint>

namespace clod_haptics {

/**
 * \brief Percentiles of a latency stream (the haptic path's pose-in to answer-out time) without storing
 * the samples: fixed bins, 1 us wide up to 1 ms, 100 us up to 100 ms, 10 ms up to 10 s, one overflow bin.
 *
 * One thread records (allocation-free, lock-free, a few relaxed atomic increments); any thread may read
 * at the same time and sees a consistent-enough snapshot (each bin is exact, the total may be a sample
 * behind). A percentile is the upper edge of the bin it falls in: never below the true value, at most one
 * bin width above it. The maximum is kept exactly.
 */
class LatencyHistogram {
 public:
  /** \brief Adds one sample in nanoseconds (negative samples count as 0). */
  void record(std::int64_t nanoseconds) noexcept;

  /** \brief Samples recorded. */
  std::uint64_t count() const noexcept { return count_.load(std::memory_order_relaxed); }

  /**
   * \brief The q-th percentile (0 < q <= 100) in microseconds, rounded up to its bin's upper edge; 0 when
   * empty, the exact maximum when it falls in the overflow bin or the top bin.
   */
  double percentileUs(double q) const noexcept;

  /** \brief The largest sample in microseconds (0 when empty). */
  double maxUs() const noexcept { return static_cast<double>(maxNs_.load(std::memory_order_relaxed)) * 1e-3; }

  /** \brief The largest sample since the last call, in microseconds, and starts a new period. */
  double takePeriodMaxUs() noexcept {
    return static_cast<double>(periodMaxNs_.exchange(0, std::memory_order_relaxed)) * 1e-3;
  }

 private:
  static constexpr int kFine = 1000;    // 0 .. 1 ms by 1 us
  static constexpr int kMiddle = 990;   // 1 ms .. 100 ms by 100 us
  static constexpr int kCoarse = 990;   // 100 ms .. 10 s by 10 ms
  static constexpr int kBins = kFine + kMiddle + kCoarse + 1;  // + overflow

  static int binOf(std::int64_t nanoseconds) noexcept;
  static double upperEdgeUs(int bin) noexcept;

  std::array<std::atomic<std::uint32_t>, kBins> bins_{};
  std::atomic<std::uint64_t> count_{0};
  std::atomic<std::int64_t> maxNs_{0};
  std::atomic<std::int64_t> periodMaxNs_{0};
};

}  // namespace clod_haptics
