#include "hal/device_clock.hpp"

#include <cerrno>
#include <stdexcept>

#include "hal/mono_clock.hpp"

namespace hapticloth::devices {

DeviceClock::DeviceClock(double period) : period_(period) {
  if (!(period > 0.0)) throw std::invalid_argument("device clock: the period must be > 0 s");
}

template <class D>
DeviceClock::Tick DeviceClock::wait_on(D& dev, double last) const noexcept {
  const double earliest = last + kEarliest * period_, latest = last + kLatest * period_;
  if (mono_now() < earliest) {
    const timespec ts = to_timespec(earliest);
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
    }
  }
  Tick t;
  t.sampled = dev.await_sample(latest);
  t.at = mono_now();
  return t;
}

DeviceClock::Tick DeviceClock::wait(DeviceHandle& dev, double last) const noexcept {
  return wait_on(dev, last);
}

DeviceClock::Tick DeviceClock::wait(Device& dev, double last) const noexcept {
  return wait_on(dev, last);
}

}  // namespace hapticloth::devices
