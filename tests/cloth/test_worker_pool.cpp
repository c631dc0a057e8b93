// The assembly's and the PCG's helper thread (server/cloth/worker_pool): every index once per
// run, on either thread, run after run; the caller's indices from the front and the helper's
// from the back; woken by a burst, spinning in it and asleep after it; the caller's waits for the
// helper counted; nothing allocated by a run.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdint>
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

// The caller's index waits until the helper has taken one (bounded: 2 s is a safety limit, not
// a figure), so the helper's share grows whenever the caller is busy.
TEST(WorkerPool, TheHelperTakesWorkWhenTheCallerIsBusy) {
  cloth::WorkerPool pool;
  const auto caller = std::this_thread::get_id();
  std::atomic<bool> helper_took{false};
  auto fn = [&](int) {
    if (std::this_thread::get_id() != caller) {
      helper_took = true;
      return;
    }
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(2);
    while (!helper_took && std::chrono::steady_clock::now() < give_up) std::this_thread::yield();
  };
  pool.run(4, fn);
  EXPECT_TRUE(helper_took);
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
// Polls `holds` every millisecond until it is true or 2 s have passed (a safety limit: on a
// loaded machine a thread may wait a scheduler slice or two for its core, never seconds).
template <class F>
bool within_2s(F&& holds) {
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(2);
  while (!holds()) {
    if (std::chrono::steady_clock::now() > give_up) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return true;
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
      if (first) {
        EXPECT_EQ(order[k], who[k] == caller ? 0 : 2) << "run " << run << ", claim " << k;
      }
      first = false;
    }
    EXPECT_FALSE(helper_first) << "run " << run << ": the helper took no index";
  }
}

// In a burst the helper spins between runs (its spin counter grows and it does not go to
// sleep); once the burst ends it goes to sleep and its spinning stops.
TEST(WorkerPool, TheHelperSpinsInABurstAndSleepsAfterIt) {
  cloth::WorkerPool pool;
  auto fn = [](int) {};
  {
    const cloth::WorkerPool::Burst burst(&pool);
    pool.run(2, fn);
    const std::uint64_t sleeps = pool.helper_sleeps(), spins = pool.helper_spin_blocks();
    EXPECT_TRUE(within_2s([&] { return pool.helper_spin_blocks() > spins + 10; })) << "the helper does not spin";
    EXPECT_EQ(pool.helper_sleeps(), sleeps) << "the helper slept in a burst";
  }
  const std::uint64_t sleeps = pool.helper_sleeps();
  EXPECT_TRUE(within_2s([&] { return pool.helper_sleeps() > sleeps; })) << "the helper still spins after the burst";
  const std::uint64_t spins = pool.helper_spin_blocks();
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_EQ(pool.helper_spin_blocks(), spins) << "the helper spins while asleep";
  pool.run(2, fn);  // and wakes for the next run
}

// The outermost burst wakes a sleeping helper before any run, so that its wake-up overlaps
// what the caller does before its first run (the contact search before a step's assembly).
TEST(WorkerPool, ABurstWakesTheHelperBeforeTheFirstRun) {
  cloth::WorkerPool pool;
  ASSERT_TRUE(within_2s([&] { return pool.helper_sleeps() > 0; })) << "the helper never went to sleep";
  const std::uint64_t spins = pool.helper_spin_blocks();
  {
    const cloth::WorkerPool::Burst burst(&pool);
    EXPECT_TRUE(within_2s([&] { return pool.helper_spin_blocks() > spins; }))
        << "the helper slept on in a burst with no run yet";
  }
  auto fn = [](int) {};
  pool.run(2, fn);  // the empty wake left the pool as it was
}

namespace {
// A clock that moves 1 ms each time it is read.
std::atomic<std::int64_t> ticking_now{0};
std::int64_t ticking_clock() { return ticking_now += 1'000'000; }
}  // namespace

// The caller's waits for the helper are counted, timed on the pool's clock (here one that moves
// 1 ms a reading: a wait is two readings). The helper's index holds until the caller has started
// its wait (read the clock), so the caller waits, once; in a run where the caller's index holds
// until the helper has finished its own, the caller has nothing to wait for and nothing is counted.
TEST(WorkerPool, TheCallersWaitsForTheHelperAreCounted) {
  cloth::WorkerPool pool(ticking_clock);
  const auto caller = std::this_thread::get_id();
  std::atomic<bool> helper_in{false};
  auto helper_last = [&](int) {
    if (std::this_thread::get_id() != caller) {
      const std::int64_t before = ticking_now;
      helper_in = true;
      within_2s([&] { return ticking_now > before; });
      return;
    }
    within_2s([&] { return helper_in.load(); });
  };
  pool.run(2, helper_last);
  ASSERT_TRUE(helper_in) << "the helper never took an index";
  EXPECT_EQ(pool.caller_wait_ns(), 1'000'000);

  const std::uint64_t share = pool.helper_share();
  auto caller_last = [&](int) {
    if (std::this_thread::get_id() == caller) within_2s([&] { return pool.helper_share() > share; });
  };
  pool.run(2, caller_last);
  ASSERT_GT(pool.helper_share(), share) << "the helper never took an index";
  EXPECT_EQ(pool.caller_wait_ns(), 1'000'000) << "a wait counted when the helper was done";
}
