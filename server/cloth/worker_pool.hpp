// One helper thread that shares a piece of work with the calling thread: run(n, fn) calls
// fn(i) once for each i in [0, n), the caller and the helper claiming the indices in turn, and
// returns when all are done. The helper sleeps on a futex (std::atomic::wait) between runs, so
// an idle pool costs nothing; a run allocates nothing. If the helper is slow to wake (or busy
// elsewhere) the caller simply takes more of the indices.
#pragma once

#include <atomic>
#include <cstdint>
#include <thread>

namespace hapticloth::cloth {

class WorkerPool {
 public:
  WorkerPool();
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  template <class F>
  void run(int n, F& fn) {
    run_raw(n, &call<F>, &fn);
  }
  /// Indices the helper took over the pool's life (the rest were the caller's).
  std::uint64_t helper_share() const { return helper_done_.load(std::memory_order_relaxed); }

 private:
  template <class F>
  static void call(void* ctx, int i) {
    (*static_cast<F*>(ctx))(i);
  }
  void run_raw(int n, void (*fn)(void*, int), void* ctx);
  void helper_loop();
  int work();

  // The run's parameters, written by the caller before it publishes them with next_.
  void (*fn_)(void*, int) = nullptr;
  void* ctx_ = nullptr;
  std::atomic<int> n_{0};
  std::atomic<int> next_{1 << 30}, done_{0};
  std::atomic<std::uint32_t> generation_{0};
  std::atomic<bool> stop_{false};
  std::atomic<std::uint64_t> helper_done_{0};
  std::thread thread_;
};

}  // namespace hapticloth::cloth
