// devices/hal/device_clock: a tick comes when a sample arrives, never sooner than half a period
// after the last tick (a burst is one tick), and at 1.5 periods without one. The rules are
// checked on an injected clock, exactly; the UDP device's own wake-up on a sample is checked over
// loopback, by whether the tick was sampled, not by when it came.

#include <gtest/gtest.h>

#include <thread>

#include "hal/device_clock.hpp"
#include "hal/mono_clock.hpp"
#include "mock/mock_device.hpp"
#include "support/loopback_socket.hpp"
#include "support/udp_packets.hpp"
#include "udp/udp_device.hpp"

namespace {

using namespace hapticloth::devices;
using hapticloth::test::LoopbackSocket;

constexpr double kPeriod = 0.001;  // s

/// Time that passes only when someone sleeps on it.
class SteppedClock final : public WakeClock {
 public:
  double now() const noexcept override { return now_; }
  void sleep_until(double t) const noexcept override {
    if (t > now_) now_ = t;
  }

 private:
  mutable double now_ = 100.0;
};

/// A device that paces the loop with samples at the given times on `clock`: await_sample
/// sleeps until the first one not yet taken (true), or until its deadline (false).
class ScriptedDevice final : public Device {
 public:
  ScriptedDevice(const SteppedClock& clock, std::vector<double> arrivals)
      : clock_(clock), arrivals_(std::move(arrivals)) {}
  const DeviceInfo& info() const override { return info_; }
  std::string configure() override { return ""; }
  std::string activate() override { return ""; }
  void deactivate() override {}
  Status read(double, DeviceState&) noexcept override { return Status::NoData; }
  Status write(double, const DeviceCommand&) noexcept override { return Status::Ok; }
  const DeviceCounters& counters() const override { return counters_; }
  bool paces_loop() const override { return true; }
  bool await_sample(double until) noexcept override {
    // Every sample that has arrived by now is read at once (a burst is one wake-up).
    bool any = false;
    while (next_ < arrivals_.size() && arrivals_[next_] <= clock_.now()) {
      ++next_;
      any = true;
    }
    if (any) return true;
    if (next_ < arrivals_.size() && arrivals_[next_] <= until) {
      clock_.sleep_until(arrivals_[next_++]);
      return true;
    }
    clock_.sleep_until(until);
    return false;
  }

 private:
  DeviceInfo info_;
  DeviceCounters counters_;
  const SteppedClock& clock_;
  std::vector<double> arrivals_;
  size_t next_ = 0;
};

TEST(DeviceClock, ASilentDeviceTicksAtOneAndAHalfPeriods) {
  SteppedClock c;
  ScriptedDevice dev(c, {});
  const DeviceClock clock(kPeriod, c);
  const double last = c.now();
  const DeviceClock::Tick t = clock.wait(dev, last);
  EXPECT_FALSE(t.sampled);
  EXPECT_DOUBLE_EQ(t.at, last + DeviceClock::kLatest * kPeriod);
}

TEST(DeviceClock, ATickComesWhenTheSampleArrives) {
  SteppedClock c;
  const double last = c.now();
  ScriptedDevice dev(c, {last + 0.8 * kPeriod, last + 2.1 * kPeriod});
  const DeviceClock clock(kPeriod, c);
  const DeviceClock::Tick t = clock.wait(dev, last);
  EXPECT_TRUE(t.sampled);
  EXPECT_DOUBLE_EQ(t.at, last + 0.8 * kPeriod);
  // The next sample is 1.3 periods after that tick: within 1.5, so it paces the next tick too.
  const DeviceClock::Tick next = clock.wait(dev, t.at);
  EXPECT_TRUE(next.sampled);
  EXPECT_DOUBLE_EQ(next.at, last + 2.1 * kPeriod);
}

TEST(DeviceClock, ABurstIsOneTickNoSoonerThanHalfAPeriod) {
  SteppedClock c;
  const double last = c.now();
  ScriptedDevice dev(c, {last + 0.1 * kPeriod, last + 0.2 * kPeriod, last + 0.3 * kPeriod});
  const DeviceClock clock(kPeriod, c);
  const DeviceClock::Tick t = clock.wait(dev, last);
  EXPECT_TRUE(t.sampled);
  EXPECT_DOUBLE_EQ(t.at, last + DeviceClock::kEarliest * kPeriod);
  // All three were taken by that tick: the next one times out.
  const DeviceClock::Tick next = clock.wait(dev, t.at);
  EXPECT_FALSE(next.sampled);
  EXPECT_DOUBLE_EQ(next.at, t.at + DeviceClock::kLatest * kPeriod);
}

TEST(DeviceClock, ASampleAfterTheLatestTickWaitsForTheNextTick) {
  SteppedClock c;
  const double last = c.now();
  ScriptedDevice dev(c, {last + 1.7 * kPeriod});
  const DeviceClock clock(kPeriod, c);
  const DeviceClock::Tick t = clock.wait(dev, last);
  EXPECT_FALSE(t.sampled);
  EXPECT_DOUBLE_EQ(t.at, last + DeviceClock::kLatest * kPeriod);
  const DeviceClock::Tick next = clock.wait(dev, t.at);  // 0.2 periods later: held to 0.5
  EXPECT_TRUE(next.sampled);
  EXPECT_DOUBLE_EQ(next.at, t.at + DeviceClock::kEarliest * kPeriod);
}

TEST(DeviceClock, OnlyAStreamingDevicePacesTheLoop) {
  UdpDevice udp(hapticloth::test::loopback_options());
  EXPECT_TRUE(udp.paces_loop());
  DeviceOptions o;
  MockDevice mock(o);
  EXPECT_FALSE(mock.paces_loop());
  SteppedClock c;
  const double t0 = c.now();
  EXPECT_FALSE(mock.await_sample(t0 + 1.0));  // at once: it does not wait on any clock
  EXPECT_THROW(DeviceClock(0.0), std::invalid_argument);
}

// A handle that is not active (never activated, or failed) has no samples to wait for: it
// answers at once, and the clock still spaces its ticks 1.5 periods apart.
TEST(DeviceClock, AnInactiveDeviceTicksAtOneAndAHalfPeriods) {
  DeviceHandle h(std::make_unique<UdpDevice>(hapticloth::test::loopback_options()));
  SteppedClock c;
  EXPECT_FALSE(h.await_sample(c.now() + 1.0));
  const DeviceClock clock(kPeriod, c);
  const double last = c.now();
  const DeviceClock::Tick t = clock.wait(h, last);
  EXPECT_FALSE(t.sampled);
  EXPECT_DOUBLE_EQ(t.at, last + DeviceClock::kLatest * kPeriod);
}

// ---- The UDP device's own wake-up, over loopback, on the monotonic clock ----

struct ActiveUdp {
  UdpDevice dev{hapticloth::test::loopback_options()};
  ActiveUdp() {
    EXPECT_EQ(dev.configure(), "");
    EXPECT_EQ(dev.activate(), "");
  }
  ~ActiveUdp() { dev.deactivate(); }
};

std::vector<std::uint8_t> packet(std::uint64_t sequence) {
  auto s = hapticloth::test::sample_state(2);
  s.sequence = sequence;
  return hapticloth::test::encode(s);
}

// A sample sent while the clock waits wakes it: the tick is sampled and reads that sample. The
// period is 1 s so that the sample, sent 0.8 s after the last tick, is 0.7 s before the tick
// would time out: only a wake-up 70x later than this machine's worst (9 ms) could turn the case.
TEST(DeviceClock, AUdpSampleWakesTheWait) {
  ActiveUdp u;
  LoopbackSocket rig;
  const double period = 1.0;
  const DeviceClock clock(period);
  const double last = mono_now();
  std::thread sender([&] {
    const timespec ts = to_timespec(last + 0.8 * period);
    clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
    rig.send_to(u.dev.local_port(), packet(1));
  });
  const DeviceClock::Tick t = clock.wait(u.dev, last);
  sender.join();
  EXPECT_TRUE(t.sampled);
  DeviceState s;
  EXPECT_EQ(u.dev.read(t.at, s), Status::Ok);
  EXPECT_EQ(s.sequence, 1u);
}

// Samples queued before the wait are one tick, which reads the newest; the next wait has
// nothing new and times out.
TEST(DeviceClock, AUdpBurstIsOneTickThatReadsTheNewest) {
  ActiveUdp u;
  LoopbackSocket rig;
  const DeviceClock clock(0.040);
  rig.send_to(u.dev.local_port(), packet(1));
  rig.send_to(u.dev.local_port(), packet(2));
  const DeviceClock::Tick t = clock.wait(u.dev, mono_now());
  EXPECT_TRUE(t.sampled);
  DeviceState s;
  EXPECT_EQ(u.dev.read(t.at, s), Status::Ok);
  EXPECT_EQ(s.sequence, 2u);
  EXPECT_FALSE(clock.wait(u.dev, t.at).sampled);
}

}  // namespace
