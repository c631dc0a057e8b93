// The clock a real-time wait reads and sleeps on. The loops use the monotonic clock
// (MonotonicClock); a test injects its own, so that a rule about when a tick comes is checked
// exactly, whatever the machine's scheduling.
#pragma once

namespace hapticloth::devices {

class WakeClock {
 public:
  virtual ~WakeClock() = default;
  /// s, on the clock that `sleep_until` deadlines are given in
  virtual double now() const noexcept = 0;
  /// Returns at `t` or later (at once if `t` has passed).
  virtual void sleep_until(double t) const noexcept = 0;
};

/// CLOCK_MONOTONIC (hal/mono_clock.hpp), slept on with clock_nanosleep(TIMER_ABSTIME).
class MonotonicClock final : public WakeClock {
 public:
  double now() const noexcept override;
  void sleep_until(double t) const noexcept override;
  /// The one instance the loops share.
  static const MonotonicClock& instance();
};

}  // namespace hapticloth::devices
