#pragma once

#include <atomic>
#include <cstdint>

namespace clod_haptics {
namespace device {

/**
 * \brief Hands the latest value of T from one writer thread to one reader thread without locks, waiting or
 * allocation: three slots, one the writer fills, one the reader holds, one in between, swapped with a single
 * atomic exchange. The writer never waits for the reader (a servo callback can publish every tick however
 * late the reader is) and the reader always gets the newest complete value. Values the reader was too slow
 * to see are overwritten, never queued. Exactly one writer thread and one reader thread.
 */
template <typename T>
class TripleBuffer {
 public:
  /** \brief The slot to fill (writer thread only); publish() makes it the latest. */
  T& back() noexcept { return slots_[back_]; }

  /** \brief Makes back() the latest value (writer thread only); the next back() is another slot. */
  void publish() noexcept {
    const std::uint8_t previous =
        middle_.exchange(static_cast<std::uint8_t>(back_ | kFresh), std::memory_order_acq_rel);
    back_ = previous & kIndex;
  }

  /**
   * \brief Takes the latest value if the writer published one since the last call (reader thread only).
   * \return true when front() changed.
   */
  bool update() noexcept {
    if (!(middle_.load(std::memory_order_relaxed) & kFresh)) return false;
    const std::uint8_t previous = middle_.exchange(front_, std::memory_order_acq_rel);
    front_ = previous & kIndex;
    return true;
  }

  /** \brief The value the reader holds (reader thread only): the latest at the last update(). */
  const T& front() const noexcept { return slots_[front_]; }

 private:
  static constexpr std::uint8_t kIndex = 0x3;
  static constexpr std::uint8_t kFresh = 0x4;
  T slots_[3]{};
  std::uint8_t back_ = 0;   // writer's
  std::uint8_t front_ = 1;  // reader's
  std::atomic<std::uint8_t> middle_{2};
};

}  // namespace device
}  // namespace clod_haptics
