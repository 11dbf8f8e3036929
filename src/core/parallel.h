#pragma once
// Internal to the core's .cpp files (not API): runs work(0..threads-1) on threads, the caller's thread
// doing part 0, and rethrows the first exception a part threw once every part has finished.

#include <algorithm>
#include <cstddef>
#include <exception>
#include <system_error>
#include <thread>
#include <vector>

namespace clod_haptics {
namespace detail {

/** \brief The most threads threadsFor gives by default: the passes are bound by memory traffic, and each
 * thread's per-cluster and per-cell arrays would make a many-core machine's peak memory grow with its cores. */
constexpr unsigned kMaxDefaultThreads = 4;

/**
 * \brief How many threads a pass over n items uses: requested (0 = the hardware's concurrency, at most
 * maxDefault), but fewer when there are under minPerThread items per thread, where starting a thread
 * costs more than it saves. Compute-bound passes (the ray casts) lift maxDefault.
 */
inline unsigned threadsFor(std::size_t n, unsigned requested, std::size_t minPerThread,
                           unsigned maxDefault = kMaxDefaultThreads) {
  const unsigned wanted =
      requested ? requested : std::min(maxDefault, std::max(1u, std::thread::hardware_concurrency()));
  return static_cast<unsigned>(std::max<std::size_t>(1, std::min<std::size_t>(wanted, n / minPerThread)));
}

/** \brief Runs work(t) for t = 0..threads-1 concurrently (work(0) on the calling thread) and joins them. */
template <class Work>
void runParallel(unsigned threads, Work&& work) {
  if (threads <= 1) {
    work(0u);
    return;
  }
  std::vector<std::exception_ptr> errors(threads);
  auto guarded = [&](unsigned t) {
    try {
      work(t);
    } catch (...) {
      errors[t] = std::current_exception();
    }
  };
  std::vector<std::thread> pool;
  pool.reserve(threads - 1);
  for (unsigned t = 1; t < threads; ++t) {
    try {
      pool.emplace_back(guarded, t);
    } catch (const std::system_error&) {
      guarded(t);  // no thread to be had: this part runs here
    }
  }
  guarded(0u);
  for (auto& th : pool) th.join();
  for (const auto& e : errors)
    if (e) std::rethrow_exception(e);
}

}  // namespace detail
}  // namespace clod_haptics
