#include "hal/device_clock.hpp"

#include <cerrno>
#include <stdexcept>

#include "hal/mono_clock.hpp"

namespace hapticloth::devices {

DeviceClock::DeviceClock(double period) : period_(period) {
  if (!(period > 0.0)) throw std::invalid_argument("device clock: the period must be > 0 s");
}

namespace {
void sleep_until(double t) {
  if (mono_now() >= t) return;
  const timespec ts = to_timespec(t);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}
}  // namespace

// A device that stops waiting before `latest` without a sample (it failed, or is not active)
// still gets its ticks 1.5 periods apart, never a burst.
template <class D>
DeviceClock::Tick DeviceClock::wait_on(D& dev, double last) const noexcept {
  const double latest = last + kLatest * period_;
  sleep_until(last + kEarliest * period_);
  Tick t;
  t.sampled = dev.await_sample(latest);
  if (!t.sampled) sleep_until(latest);
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
