// Latest-value handoff between one writer thread and one reader thread: no lock, no allocation
// after construction. The writer fills back(), then publish(); the reader calls acquire() and
// reads front() until its next acquire(). Three slots: the writer never waits for the reader.
#pragma once

#include <atomic>
#include <cstdint>

namespace hapticloth::haptics {

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
  T& front_mut() { return slot_[front_]; }

  static constexpr bool lock_free() { return std::atomic<std::uint8_t>::is_always_lock_free; }

 private:
  static constexpr std::uint8_t kNew = 0x4, kIndex = 0x3;
  T slot_[3];
  std::uint8_t back_ = 0, front_ = 1;
  std::atomic<std::uint8_t> middle_{2};
};

}  // namespace hapticloth::haptics
