#include "hal/wake_clock.hpp"

#include <cerrno>

#include "hal/mono_clock.hpp"

namespace hapticloth::devices {

double MonotonicClock::now() const noexcept { return mono_now(); }

void MonotonicClock::sleep_until(double t) const noexcept {
  if (mono_now() >= t) return;
  const timespec ts = to_timespec(t);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

const MonotonicClock& MonotonicClock::instance() {
  static const MonotonicClock clock;
  return clock;
}

}  // namespace hapticloth::devices
