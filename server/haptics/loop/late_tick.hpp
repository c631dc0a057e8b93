// The fingertip a late tick hands the contact: the kernel now and then wakes the haptic thread
// 1-9 ms late (docs/haptic-loop.md), and the device's fingertip has moved on by v L meanwhile.
// Handed over at once, that motion reaches the coupling spring in one tick: a force step of
// k v L (0.8 N at 50 mm/s and L = 20 ms, against 0.04 N a tick on time) and a push on the cloth
// the user never made that fast. So after a tick that comes L late the fingertip the contact sees
// catches up over the ticks that were missed, 1 + L / T of them, a share of the remaining gap
// each tick: the force then changes tick by tick as it does on time. What the catch-up holds
// back, the passivity observer (passivity.hpp) accounts for. Real-time safe.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

#include "haptics/sim/handoff.hpp"

namespace hapticloth::haptics {

class LateTickCatchUp {
 public:
  explicit LateTickCatchUp(double nominal_dt) : dt_(nominal_dt) {}

  /// The fingertip finger f's contact sees this tick, given the device's `measured` fingertip
  /// and the measured interval since the last tick `tick_dt` (s).
  Vec3 seen(int f, const Vec3& measured, double tick_dt) noexcept {
    Finger& s = fs_[f];
    if (!s.have) {
      s = Finger{true, measured, 0};
      return measured;
    }
    if (late(tick_dt))  // the missed ticks and this one share the motion
      s.remaining = std::max(s.remaining, static_cast<int>(std::lround(tick_dt / dt_)));
    if (s.remaining > 0) {
      s.at += (measured - s.at) / s.remaining;
      --s.remaining;
      ++catch_up_ticks_;
    } else {
      s.at = measured;
    }
    return s.at;
  }
  void reset(int f) noexcept { fs_[f] = Finger{}; }
  /// A tick is late when it comes more than half a period after its time.
  bool late(double tick_dt) const noexcept { return tick_dt > 1.5 * dt_; }

  /// Ticks on which a finger's contact saw a fingertip still catching up.
  std::uint64_t catch_up_ticks() const { return catch_up_ticks_; }

 private:
  struct Finger {
    bool have = false;
    Vec3 at = Vec3::Zero();
    int remaining = 0;
  };
  double dt_;
  std::array<Finger, kMaxFingers> fs_{};
  std::uint64_t catch_up_ticks_ = 0;
};

}  // namespace hapticloth::haptics
