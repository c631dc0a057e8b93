// A single-producer single-consumer ring of fixed capacity: the real-time thread pushes (never
// allocates, never blocks: a full ring refuses the item), another thread pops. Lock-free.
#pragma once

#include <atomic>
#include <cstddef>
#include <vector>

namespace hapticloth::devices {

template <class T>
class SpscRing {
 public:
  /// Set-up only: allocates room for `capacity` items.
  explicit SpscRing(std::size_t capacity) : buf_(capacity + 1) {}

  /// Producer. False (and nothing stored) if the ring is full.
  bool push(const T& item) noexcept {
    const std::size_t h = head_.load(std::memory_order_relaxed);
    const std::size_t next = h + 1 == buf_.size() ? 0 : h + 1;
    if (next == tail_.load(std::memory_order_acquire)) return false;
    buf_[h] = item;
    head_.store(next, std::memory_order_release);
    return true;
  }

  /// Consumer. False if the ring is empty.
  bool pop(T& item) noexcept {
    const std::size_t t = tail_.load(std::memory_order_relaxed);
    if (t == head_.load(std::memory_order_acquire)) return false;
    item = buf_[t];
    tail_.store(t + 1 == buf_.size() ? 0 : t + 1, std::memory_order_release);
    return true;
  }

  std::size_t capacity() const { return buf_.size() - 1; }

 private:
  std::vector<T> buf_;
  alignas(64) std::atomic<std::size_t> head_{0};
  alignas(64) std::atomic<std::size_t> tail_{0};
};

}  // namespace hapticloth::devices
