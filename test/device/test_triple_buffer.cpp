// TripleBuffer: the reader gets the newest published value, never a half-written one, and the writer
// never waits, checked against the sequence the writer wrote.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdint>
#include <thread>

#include "clod_haptics/device/triple_buffer.h"

using clod_haptics::device::TripleBuffer;

namespace {
struct Pair {
  std::uint64_t value;
  std::uint64_t check;  // always ~value in a complete write
};
}  // namespace

TEST(TripleBuffer, ReaderSeesNothingBeforeTheFirstPublish) {
  TripleBuffer<int> buffer;
  EXPECT_FALSE(buffer.update());
  EXPECT_EQ(buffer.front(), 0);
}

TEST(TripleBuffer, ReaderGetsTheNewestOfSeveralPublishes) {
  TripleBuffer<int> buffer;
  for (int i = 1; i <= 5; ++i) {
    buffer.back() = i;
    buffer.publish();
  }
  ASSERT_TRUE(buffer.update());
  EXPECT_EQ(buffer.front(), 5);
  EXPECT_FALSE(buffer.update());  // nothing new: front() stays
  EXPECT_EQ(buffer.front(), 5);
  buffer.back() = 6;
  buffer.publish();
  ASSERT_TRUE(buffer.update());
  EXPECT_EQ(buffer.front(), 6);
}

TEST(TripleBuffer, ConcurrentReaderSeesCompleteIncreasingValues) {
  TripleBuffer<Pair> buffer;
  constexpr std::uint64_t kWrites = 200000;
  std::atomic<bool> done{false};
  std::thread writer([&] {
    for (std::uint64_t i = 1; i <= kWrites; ++i) {
      Pair& p = buffer.back();
      p.value = i;
      p.check = ~i;
      buffer.publish();
    }
    done = true;
  });
  std::uint64_t last = 0, torn = 0, backwards = 0;
  bool finished = false;
  while (!finished) {
    finished = done.load();  // after it is true, the update below sees the last publish
    if (buffer.update()) {
      const Pair& p = buffer.front();
      if (p.check != ~p.value) ++torn;
      if (p.value <= last) ++backwards;
      last = p.value;
    }
  }
  writer.join();
  EXPECT_EQ(torn, 0u);
  EXPECT_EQ(backwards, 0u);
  EXPECT_EQ(last, kWrites);  // the last value published is the last one read
}
