// The real-time handoffs (devices/hal/rt_handoff.hpp): the latest value across threads, and
// the fixed ring that refuses rather than blocks.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <thread>

#include "hal/rt_handoff.hpp"

using namespace hapticloth;

TEST(TripleBuffer, LatestValueWithoutLocksAcrossThreads) {
  static_assert(devices::TripleBuffer<int>::lock_free());
  devices::TripleBuffer<long> tb(0);
  std::atomic<bool> done{false};
  long seen_max = 0, regressions = 0;
  std::thread reader([&] {
    for (int i = 0; i < 2000000 && !done; ++i) {
      if (tb.acquire()) {
        if (tb.front() < seen_max) ++regressions;
        seen_max = std::max(seen_max, tb.front());
      }
    }
  });
  for (long k = 1; k <= 200000; ++k) {
    tb.back() = k;
    tb.publish();
  }
  done = true;
  reader.join();
  EXPECT_EQ(regressions, 0);  // values only move forward
  tb.acquire();
  EXPECT_EQ(tb.front(), 200000);  // the newest is never lost
}

TEST(SpscRing, FullRingRefusesAndOrderIsKept) {
  devices::SpscRing<int> ring(3);
  EXPECT_EQ(ring.capacity(), 3u);
  for (int i = 1; i <= 3; ++i) EXPECT_TRUE(ring.push(i));
  EXPECT_FALSE(ring.push(4));  // full: refused, nothing overwritten
  int v = 0;
  for (int i = 1; i <= 3; ++i) {
    ASSERT_TRUE(ring.pop(v));
    EXPECT_EQ(v, i);
  }
  EXPECT_FALSE(ring.pop(v));
}

// Both sides are bounded by a 20 s deadline and yield when they cannot proceed: on 2 cores
// under load either thread may be off the CPU for a long while.
TEST(SpscRing, EveryItemArrivesOnceAcrossThreads) {
  devices::SpscRing<long> ring(64);
  const long n = 200000;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  long sum = 0, got = 0, last = 0;
  bool ordered = true;
  std::thread consumer([&] {
    long v;
    while (got < n && std::chrono::steady_clock::now() < deadline) {
      if (!ring.pop(v)) {
        std::this_thread::yield();
        continue;
      }
      ordered = ordered && v == last + 1;
      last = v;
      sum += v;
      ++got;
    }
  });
  for (long k = 1; k <= n && std::chrono::steady_clock::now() < deadline;)
    if (ring.push(k)) ++k;
    else std::this_thread::yield();
  consumer.join();
  EXPECT_EQ(got, n);
  EXPECT_TRUE(ordered);
  EXPECT_EQ(sum, n * (n + 1) / 2);
}
