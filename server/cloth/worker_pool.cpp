#include "cloth/worker_pool.hpp"

#include <chrono>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

namespace hapticloth::cloth {

std::int64_t WorkerPool::steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

WorkerPool::WorkerPool(NanoClock clock) : clock_(clock), thread_([this] { helper_loop(); }) {}

WorkerPool::~WorkerPool() {
  stop_.store(true, std::memory_order_release);
  generation_.fetch_add(1, std::memory_order_release);
  generation_.notify_one();
  thread_.join();
}

// The next unclaimed index, from the front (the caller) or the back (the helper); -1 if none is
// left. The caller and the helper so take the same indices run after run when both are there
// (the same rows, whose data then stays in their own core's cache: with the indices to
// whichever thread came first, two threads gained nothing; docs/performance.md, 'Performance of
// the step').
int WorkerPool::claim(bool from_back) {
  std::uint64_t cur = range_.load(std::memory_order_acquire);
  for (;;) {
    const auto front = static_cast<std::uint32_t>(cur), back = static_cast<std::uint32_t>(cur >> 32);
    if (front >= back) return -1;
    const std::uint64_t next = from_back ? (std::uint64_t(back - 1) << 32 | front)
                                         : (std::uint64_t(back) << 32 | (front + 1));
    if (range_.compare_exchange_weak(cur, next, std::memory_order_acq_rel, std::memory_order_acquire))
      return static_cast<int>(from_back ? back - 1 : front);
  }
}

// Claims indices until none is left; returns how many this thread did.
int WorkerPool::work(bool from_back) {
  int did = 0;
  for (int i; (i = claim(from_back)) >= 0; ++did) {
    fn_(ctx_, i);
    done_.fetch_add(1, std::memory_order_acq_rel);
  }
  return did;
}

void WorkerPool::run_raw(int n, void (*fn)(void*, int), void* ctx) {
  if (n <= 0) return;
  fn_ = fn;
  ctx_ = ctx;
  done_.store(0, std::memory_order_relaxed);
  range_.store(std::uint64_t(n) << 32, std::memory_order_release);  // publishes the run: a claim reads it first
  generation_.fetch_add(1, std::memory_order_release);
  generation_.notify_one();
  work(false);
  // The helper may still be inside its last index: wait for it (a few tens of us at most).
  if (done_.load(std::memory_order_acquire) == n) return;
  const std::int64_t t0 = clock_();
  spin_while([&] { return done_.load(std::memory_order_acquire) < n; });
  caller_wait_ns_ += clock_() - t0;
}

// A new generation with no index to claim: the helper wakes, finds nothing, and (in a burst)
// spins until the next run.
void WorkerPool::wake() {
  generation_.fetch_add(1, std::memory_order_release);
  generation_.notify_one();
}

void WorkerPool::pause() {
#if defined(__x86_64__) || defined(__i386__)
  _mm_pause();
#else
  std::this_thread::yield();
#endif
}

void WorkerPool::helper_loop() {
  std::uint32_t seen = 0;
  for (;;) {
    // In a burst, spin until the next run (or the burst's end); then sleep as usual.
    spin_while(
        [&] {
          return bursts_.load(std::memory_order_acquire) > 0 && generation_.load(std::memory_order_acquire) == seen;
        },
        &helper_spin_blocks_);
    if (generation_.load(std::memory_order_acquire) == seen) helper_sleeps_.fetch_add(1, std::memory_order_relaxed);
    generation_.wait(seen, std::memory_order_acquire);
    seen = generation_.load(std::memory_order_acquire);
    if (stop_.load(std::memory_order_acquire)) return;
    helper_done_.fetch_add(work(true), std::memory_order_relaxed);
  }
}

}  // namespace hapticloth::cloth
