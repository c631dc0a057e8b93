// Ticks paced by a device that streams on its own clock (a UDP rig): the loop ticks when the
// device's sample arrives, so the force answers it after one wake-up and one tick's compute
// instead of waiting for the loop's own next deadline (0 to 1 period later, uniformly, when the
// two clocks run free: a rig cannot know the server's phase).
//
// A tick comes no sooner than half a period after the last one (a burst of samples is one
// tick) and no later than 1.5 periods after it without a sample (a silent device still gets
// ticks: its state goes stale and the safety gate ramps the force out).
#pragma once

#include "hal/device.hpp"
#include "hal/handle.hpp"
#include "hal/wake_clock.hpp"

namespace hapticloth::devices {

class DeviceClock {
 public:
  /// `period`: the loop's nominal period, s (> 0). `clock`: what the waits read and sleep on
  /// (the device's await_sample deadlines are on it too); it must outlive this.
  explicit DeviceClock(double period, const WakeClock& clock = MonotonicClock::instance());

  struct Tick {
    double at = 0.0;       ///< CLOCK_MONOTONIC, s: when the loop woke for this tick
    bool sampled = false;  ///< a sample arrived (else the tick timed out at 1.5 periods)
  };
  /// Blocks until the next tick after the one at `last` (CLOCK_MONOTONIC, s). Real-time path.
  Tick wait(DeviceHandle& dev, double last) const noexcept;
  Tick wait(Device& dev, double last) const noexcept;

  static constexpr double kEarliest = 0.5;  ///< periods after the last tick
  static constexpr double kLatest = 1.5;    ///< periods after the last tick

 private:
  template <class D>
  Tick wait_on(D& dev, double last) const noexcept;
  double period_;
  const WakeClock* clock_;
};

}  // namespace hapticloth::devices
