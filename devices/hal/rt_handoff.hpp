// The real-time handoffs between threads, in one place: neither takes a lock, and neither
// allocates after construction.
//   TripleBuffer: the latest value from one writer to one reader (the cloth snapshot to the
//     haptic thread, its report back, a remote device's newest plan). Three slots: the writer
//     never waits for the reader, and the reader always gets the newest complete value.
//   SpscRing: a queue of fixed capacity from one producer to one consumer (the device log's
//     rows): a full ring refuses the item instead of blocking the real-time thread.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace hapticloth::devices {

/// The writer fills back(), then publish(); the reader calls acquire() and reads front() until
/// its next acquire().
template <class T>
class TripleBuffer {
 public:
  /// `init` is copied into all three slots (so every slot's storage is allocated up front).
  explicit TripleBuffer(const T& init) : slot_{init, init, init} {}

  T& back() { return slot_[back_]; }
  /// Makes back() the newest value; the writer gets a free slot as its new back().
  void publish() {
    const std::uint8_t prev = middle_.exchange(static_cast<std::uint8_t>(back_ | kNew), std::memory_order_acq_rel);
    back_ = prev & kIndex;
  }

  /// Takes the newest published value if there is one; returns true if front() changed.
  bool acquire() {
    if (!(middle_.load(std::memory_order_acquire) & kNew)) return false;
    const std::uint8_t prev = middle_.exchange(front_, std::memory_order_acq_rel);
    front_ = prev & kIndex;
    return true;
  }
  const T& front() const { return slot_[front_]; }

  static constexpr bool lock_free() { return std::atomic<std::uint8_t>::is_always_lock_free; }

 private:
  static constexpr std::uint8_t kNew = 0x4, kIndex = 0x3;
  T slot_[3];
  std::uint8_t back_ = 0, front_ = 1;
  std::atomic<std::uint8_t> middle_{2};
};

/// Single producer, single consumer; the producer is the real-time side.
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
