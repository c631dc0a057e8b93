#include "cloth/worker_pool.hpp"

namespace hapticloth::cloth {

WorkerPool::WorkerPool() : thread_([this] { helper_loop(); }) {}

WorkerPool::~WorkerPool() {
  stop_.store(true, std::memory_order_release);
  generation_.fetch_add(1, std::memory_order_release);
  generation_.notify_one();
  thread_.join();
}

// Claims indices until none is left; returns how many this thread did.
int WorkerPool::work() {
  int did = 0;
  for (;;) {
    const int i = next_.fetch_add(1, std::memory_order_acq_rel);
    if (i >= n_.load(std::memory_order_relaxed)) return did;
    fn_(ctx_, i);
    done_.fetch_add(1, std::memory_order_acq_rel);
    ++did;
  }
}

void WorkerPool::run_raw(int n, void (*fn)(void*, int), void* ctx) {
  if (n <= 0) return;
  fn_ = fn;
  ctx_ = ctx;
  n_.store(n, std::memory_order_relaxed);
  done_.store(0, std::memory_order_relaxed);
  next_.store(0, std::memory_order_release);  // publishes the run: a claim reads it first
  generation_.fetch_add(1, std::memory_order_release);
  generation_.notify_one();
  work();
  // The helper may still be inside its last index: wait for it (a few tens of us at most).
  while (done_.load(std::memory_order_acquire) < n) std::this_thread::yield();
  next_.store(1 << 30, std::memory_order_release);  // nothing to claim until the next run
}

void WorkerPool::helper_loop() {
  std::uint32_t seen = 0;
  for (;;) {
    generation_.wait(seen, std::memory_order_acquire);
    seen = generation_.load(std::memory_order_acquire);
    if (stop_.load(std::memory_order_acquire)) return;
    helper_done_.fetch_add(work(), std::memory_order_relaxed);
  }
}

}  // namespace hapticloth::cloth
