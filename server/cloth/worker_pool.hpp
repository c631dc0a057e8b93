// One helper thread that shares a piece of work with the calling thread: run(n, fn) calls
// fn(i) once for each i in [0, n), the caller claiming indices from the front and the helper
// from the back, and returns when all are done. The helper sleeps on a futex
// (std::atomic::wait) between runs, so an idle pool costs nothing; a run allocates nothing. If
// the helper is slow to wake (or busy elsewhere) the caller simply takes more of the indices.
// Within a Burst the helper spins between runs instead: a futex wake costs as much as the two
// runs of a PCG iteration or more (docs/performance.md, 'Performance of the step').
// A spinning helper takes its core from threads of normal priority; the haptic thread runs at a
// real-time priority (SCHED_FIFO when permitted), which preempts it.
#pragma once

#include <atomic>
#include <cstdint>
#include <thread>

namespace hapticloth::cloth {

class WorkerPool {
 public:
  /// What the caller's waits are timed with, in ns (a test injects its own).
  using NanoClock = std::int64_t (*)();
  static std::int64_t steady_ns();

  explicit WorkerPool(NanoClock clock = steady_ns);
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  template <class F>
  void run(int n, F& fn) {
    run_raw(n, &call<F>, &fn);
  }
  /// While one is alive, the helper spins between runs (burning its core) instead of sleeping:
  /// for a sequence of short runs, such as a time step's assembly and solves. Nests. The
  /// outermost one wakes the helper at once, so that the futex wake-up overlaps whatever the
  /// caller does before its first run instead of delaying that run.
  class Burst {
   public:
    explicit Burst(WorkerPool* pool) : pool_(pool) {
      if (pool_ && pool_->bursts_.fetch_add(1, std::memory_order_acq_rel) == 0) pool_->wake();
    }
    ~Burst() {
      if (pool_) pool_->bursts_.fetch_sub(1, std::memory_order_release);
    }
    Burst(const Burst&) = delete;
    Burst& operator=(const Burst&) = delete;

   private:
    WorkerPool* pool_;
  };
  /// Time the caller spent waiting at the ends of runs for the helper to finish its last index,
  /// over the pool's life, in nanoseconds: a helper slowed down (its core taken by another
  /// thread, or by the host) shows here. Read by the calling thread.
  std::int64_t caller_wait_ns() const { return caller_wait_ns_; }
  /// Indices the helper took over the pool's life (the rest were the caller's).
  std::uint64_t helper_share() const { return helper_done_.load(std::memory_order_relaxed); }
  /// How the helper spends the time between runs, over the pool's life: the times it went to
  /// sleep on the futex, and its spins between runs in thousands of rounds (1024 each).
  std::uint64_t helper_sleeps() const { return helper_sleeps_.load(std::memory_order_relaxed); }
  std::uint64_t helper_spin_blocks() const { return helper_spin_blocks_.load(std::memory_order_relaxed); }

 private:
  template <class F>
  static void call(void* ctx, int i) {
    (*static_cast<F*>(ctx))(i);
  }
  void run_raw(int n, void (*fn)(void*, int), void* ctx);
  void wake();
  void helper_loop();
  static void pause();
  // Spins while keep() holds, giving the core away every 1024 rounds (in case the thread waited
  // for shares it); `blocks` counts those rounds.
  template <class F>
  static void spin_while(F&& keep, std::atomic<std::uint64_t>* blocks = nullptr) {
    for (int spins = 1; keep(); ++spins)
      if (spins % 1024 == 0) {
        if (blocks) blocks->fetch_add(1, std::memory_order_relaxed);
        std::this_thread::yield();
      } else {
        pause();
      }
  }
  int claim(bool from_back);
  int work(bool from_back);

  // The run's parameters, written by the caller before it publishes them with range_.
  void (*fn_)(void*, int) = nullptr;
  void* ctx_ = nullptr;
  std::atomic<std::uint64_t> range_{0};  // the unclaimed indices [front, back): back in the high half
  std::atomic<int> done_{0};
  std::atomic<std::uint32_t> generation_{0};
  std::atomic<bool> stop_{false};
  std::atomic<int> bursts_{0};
  std::atomic<std::uint64_t> helper_done_{0};
  std::atomic<std::uint64_t> helper_sleeps_{0};
  std::atomic<std::uint64_t> helper_spin_blocks_{0};
  NanoClock clock_;
  std::int64_t caller_wait_ns_ = 0;
  std::thread thread_;
};

}  // namespace hapticloth::cloth
