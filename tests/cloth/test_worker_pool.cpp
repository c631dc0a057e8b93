// The assembly's and the PCG's helper thread (server/cloth/worker_pool): every index once per
// run, on either thread, run after run; the caller's indices from the front and the helper's
// from the back; woken by a burst, spinning in it and asleep after it; the caller's waits for the
// helper counted; nothing allocated by a run.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <ctime>
#include <thread>
#include <vector>

#include "cloth/worker_pool.hpp"
#include "support/alloc_counter.hpp"

using namespace hapticloth;

TEST(WorkerPool, RunsEveryIndexOncePerRun) {
  cloth::WorkerPool pool;
  std::vector<std::atomic<int>> hits(8);
  for (int run = 0; run < 4000; ++run) {
    const cloth::WorkerPool::Burst burst(run >= 2000 ? &pool : nullptr);  // woken, then spinning
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

namespace {
// The process's CPU time (all threads), s.
double cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}
void spin_for(std::chrono::microseconds d) {
  const auto end = std::chrono::steady_clock::now() + d;
  while (std::chrono::steady_clock::now() < end) {
  }
}
}  // namespace

// The caller claims from the front and the helper from the back, so with both there each keeps
// its indices run after run (a PCG part's rows stay in one core's cache): in every run the
// caller's first index, if it took any, is 0, and the helper's is the last. Whoever takes index 0
// holds it until index 2 has started, so the helper takes part in every run.
TEST(WorkerPool, TheCallerTakesTheFrontAndTheHelperTheBack) {
  cloth::WorkerPool pool;
  const auto caller = std::this_thread::get_id();
  std::thread::id who[3];
  std::atomic<int> claims{0};
  std::atomic<bool> back_started{false};
  bool waited_out = false;
  int order[3];
  auto fn = [&](int i) {
    const int k = claims.fetch_add(1);
    who[k] = std::this_thread::get_id();
    order[k] = i;
    if (i == 2) back_started.store(true);
    if (i != 0) return;
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(2);
    while (!back_started.load() && !waited_out) waited_out = std::chrono::steady_clock::now() > give_up;
  };
  for (int run = 0; run < 20; ++run) {
    back_started.store(false);
    claims.store(0);
    pool.run(3, fn);
    ASSERT_FALSE(waited_out) << "run " << run << ": index 2 never started while 0 was held";
    bool caller_first = true, helper_first = true;
    for (int k = 0; k < 3; ++k) {
      bool& first = who[k] == caller ? caller_first : helper_first;
      if (first) EXPECT_EQ(order[k], who[k] == caller ? 0 : 2) << "run " << run << ", claim " << k;
      first = false;
    }
    EXPECT_FALSE(helper_first) << "run " << run << ": the helper took no index";
  }
}

// In a burst the helper spins between runs (its core busy while the caller is idle); once the
// burst ends it sleeps again.
TEST(WorkerPool, TheHelperSpinsInABurstAndSleepsAfterIt) {
  cloth::WorkerPool pool;
  auto fn = [](int) {};
  double busy = 0.0;
  {
    const cloth::WorkerPool::Burst burst(&pool);
    pool.run(2, fn);
    // 10 ms of CPU while this thread sleeps: a spinning helper has it within 10-50 ms, even on
    // a busy machine (ctest -j2); one asleep would not in the 2 s allowed.
    const double c0 = cpu_seconds();
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(2);
    while (cpu_seconds() - c0 < 0.01 && std::chrono::steady_clock::now() < give_up)
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    busy = cpu_seconds() - c0;
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(5));  // the helper sees the burst end
  const double c1 = cpu_seconds();
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  const double idle = cpu_seconds() - c1;
  EXPECT_GE(busy, 0.01) << "the helper slept in a burst";
  EXPECT_LT(idle, 0.01) << "the helper still spins after the burst";
  pool.run(2, fn);  // and wakes for the next run
}

// The outermost burst wakes a sleeping helper before any run, so that its wake-up overlaps
// what the caller does before its first run (the contact search before a step's assembly).
TEST(WorkerPool, ABurstWakesTheHelperBeforeTheFirstRun) {
  cloth::WorkerPool pool;
  std::this_thread::sleep_for(std::chrono::milliseconds(20));  // the helper asleep
  double busy = 0.0;
  {
    const cloth::WorkerPool::Burst burst(&pool);
    // Over 0.3 s of this thread sleeping, a spinning helper takes 0.1-0.3 s of CPU (half a core
    // or more, even under ctest -j2); an asleep one, with this loop, about 3 ms.
    const double c0 = cpu_seconds();
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    busy = cpu_seconds() - c0;
  }
  EXPECT_GE(busy, 0.05) << "the helper slept on in a burst with no run yet";
  auto fn = [](int) {};
  pool.run(2, fn);  // the empty wake left the pool as it was
}

// The caller's waits for a slow helper are counted: the helper's index takes 100 ms, the
// caller's none (it waits, bounded, until the helper has claimed one), so the caller waits
// nearly 100 ms (50 ms or more even if it is descheduled on a busy machine); a run of one quick
// index adds little.
TEST(WorkerPool, TheCallersWaitsForTheHelperAreCounted) {
  cloth::WorkerPool pool;
  const auto caller = std::this_thread::get_id();
  std::atomic<bool> helper_in{false};
  auto fn = [&](int) {
    if (std::this_thread::get_id() != caller) {
      helper_in = true;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      return;
    }
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(2);
    while (!helper_in && std::chrono::steady_clock::now() < give_up) std::this_thread::yield();
  };
  pool.run(2, fn);
  ASSERT_TRUE(helper_in) << "the helper never took an index";
  const std::int64_t waited = pool.caller_wait_ns();
  EXPECT_GE(waited, 50'000'000) << "a 100 ms index of the helper's, waited for";
  EXPECT_LT(waited, 2'000'000'000);
  auto quick = [](int) {};
  pool.run(1, quick);  // one index: the caller's (or the helper's, then waited for briefly)
  EXPECT_LT(pool.caller_wait_ns() - waited, 50'000'000);
}
