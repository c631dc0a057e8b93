#include "hal/device_clock.hpp"

#include <stdexcept>

namespace hapticloth::devices {

DeviceClock::DeviceClock(double period, const WakeClock& clock) : period_(period), clock_(&clock) {
  if (!(period > 0.0)) throw std::invalid_argument("device clock: the period must be > 0 s");
}

// A device that stops waiting before `latest` without a sample (it failed, or is not active)
// still gets its ticks 1.5 periods apart, never a burst.
template <class D>
DeviceClock::Tick DeviceClock::wait_on(D& dev, double last) const noexcept {
  const double latest = last + kLatest * period_;
  clock_->sleep_until(last + kEarliest * period_);
  Tick t;
  t.sampled = dev.await_sample(latest);
  if (!t.sampled) clock_->sleep_until(latest);
  t.at = clock_->now();
  return t;
}

DeviceClock::Tick DeviceClock::wait(DeviceHandle& dev, double last) const noexcept {
  return wait_on(dev, last);
}

DeviceClock::Tick DeviceClock::wait(Device& dev, double last) const noexcept {
  return wait_on(dev, last);
}

}  // namespace hapticloth::devices
