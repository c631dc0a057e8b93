// Latest-value handoff from one writer thread to one reader thread: three slots, no lock, no
// allocation after construction (the same scheme as haptics::TripleBuffer, kept here so the
// device library does not depend on the haptics library).
#pragma once

#include <atomic>
#include <cstdint>

namespace hapticloth::devices {

template <class T>
class Latest {
 public:
  explicit Latest(const T& init) : slot_{init, init, init} {}
  /// Writer: fill back(), then publish().
  T& back() { return slot_[back_]; }
  void publish() {
    back_ = middle_.exchange(static_cast<std::uint8_t>(back_ | kNew), std::memory_order_acq_rel) & kIndex;
  }
  /// Reader: true if a newer value was taken into front().
  bool acquire() noexcept {
    if (!(middle_.load(std::memory_order_acquire) & kNew)) return false;
    front_ = middle_.exchange(front_, std::memory_order_acq_rel) & kIndex;
    return true;
  }
  const T& front() const noexcept { return slot_[front_]; }

 private:
  static constexpr std::uint8_t kNew = 0x4, kIndex = 0x3;
  T slot_[3];
  std::uint8_t back_ = 0, front_ = 1;
  std::atomic<std::uint8_t> middle_{2};
};

}  // namespace hapticloth::devices
