// The assembly's helper thread (server/cloth/worker_pool): every index once per run, on either
// thread, run after run, and nothing allocated by a run.
#include <gtest/gtest.h>

#include <atomic>
#include <vector>

#include "cloth/worker_pool.hpp"
#include "support/alloc_counter.hpp"

using namespace hapticloth;

TEST(WorkerPool, RunsEveryIndexOncePerRun) {
  cloth::WorkerPool pool;
  std::vector<std::atomic<int>> hits(8);
  for (int run = 0; run < 2000; ++run) {
    const int n = 1 + run % 8;
    for (auto& h : hits) h.store(0);
    auto fn = [&](int i) { hits[i].fetch_add(1); };
    pool.run(n, fn);
    for (int i = 0; i < 8; ++i) ASSERT_EQ(hits[i].load(), i < n ? 1 : 0) << "run " << run << " index " << i;
  }
}

TEST(WorkerPool, TheHelperTakesWorkWhenTheCallerIsBusy) {
  cloth::WorkerPool pool;
  // Each index spins for 2 ms: the caller cannot take all four before the helper wakes.
  auto slow = [](int) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(2);
    while (std::chrono::steady_clock::now() < end) {
    }
  };
  for (int run = 0; run < 10; ++run) pool.run(4, slow);
  EXPECT_GT(pool.helper_share(), 0u);
}

TEST(WorkerPool, ARunAllocatesNothing) {
  cloth::WorkerPool pool;
  int sum = 0;
  auto fn = [&](int i) { sum += i * 0; };
  pool.run(4, fn);
  test::AllocationGuard guard;
  for (int run = 0; run < 100; ++run) pool.run(4, fn);
  EXPECT_EQ(guard.count(), 0u);
}
