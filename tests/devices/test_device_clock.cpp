// devices/hal/device_clock: ticks paced by the UDP device over loopback. A tick comes when a
// sample arrives, never sooner than half a period after the last tick, and at 1.5 periods
// without one. The period here is 40 ms, so that the machine's occasional late wake-up (up to
// 9 ms seen) cannot turn one case into another. Every wait is bounded by the clock itself.

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

constexpr double kPeriod = 0.040;     // s
constexpr double kLateBound = 0.015;  // s: above the latest wake-up seen on this machine (9 ms)

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

TEST(DeviceClock, ASilentDeviceStillTicksAtOneAndAHalfPeriods) {
  ActiveUdp u;
  const DeviceClock clock(kPeriod);
  const double last = mono_now();
  const DeviceClock::Tick t = clock.wait(u.dev, last);
  EXPECT_FALSE(t.sampled);
  EXPECT_GE(t.at - last, DeviceClock::kLatest * kPeriod - 1e-4);
  EXPECT_LT(t.at - last, DeviceClock::kLatest * kPeriod + kLateBound);
}

TEST(DeviceClock, ATickComesWhenTheSampleArrives) {
  ActiveUdp u;
  LoopbackSocket rig;
  const DeviceClock clock(kPeriod);
  const double last = mono_now();
  double sent = 0.0;
  std::thread sender([&] {  // 0.8 periods after the last tick: between the earliest and latest
    const timespec ts = to_timespec(last + 0.8 * kPeriod);
    clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
    sent = mono_now();
    rig.send_to(u.dev.local_port(), packet(1));
  });
  const DeviceClock::Tick t = clock.wait(u.dev, last);
  sender.join();
  EXPECT_TRUE(t.sampled);
  EXPECT_GE(t.at, sent);
  EXPECT_LT(t.at - sent, kLateBound);
  EXPECT_LT(t.at - last, DeviceClock::kLatest * kPeriod);
  DeviceState s;
  EXPECT_EQ(u.dev.read(t.at, s), Status::Ok);
  EXPECT_EQ(s.sequence, 1u);
}

TEST(DeviceClock, ABurstIsOneTickNoSoonerThanHalfAPeriod) {
  ActiveUdp u;
  LoopbackSocket rig;
  const DeviceClock clock(kPeriod);
  const double last = mono_now();
  rig.send_to(u.dev.local_port(), packet(1));
  rig.send_to(u.dev.local_port(), packet(2));
  const DeviceClock::Tick t = clock.wait(u.dev, last);
  EXPECT_TRUE(t.sampled);
  EXPECT_GE(t.at - last, DeviceClock::kEarliest * kPeriod);
  DeviceState s;
  EXPECT_EQ(u.dev.read(t.at, s), Status::Ok);
  EXPECT_EQ(s.sequence, 2u);  // the newest of the burst
  // Both were read by that tick: the next waits for a new sample, or times out.
  const DeviceClock::Tick next = clock.wait(u.dev, t.at);
  EXPECT_FALSE(next.sampled);
}

TEST(DeviceClock, OnlyAStreamingDevicePacesTheLoop) {
  ActiveUdp u;
  EXPECT_TRUE(u.dev.paces_loop());
  DeviceOptions o;
  MockDevice mock(o);
  EXPECT_FALSE(mock.paces_loop());
  EXPECT_FALSE(mock.await_sample(mono_now() + 1.0));  // at once, not after 1 s
  EXPECT_THROW(DeviceClock(0.0), std::invalid_argument);
}

// A handle that is not active (never activated, or failed) has no samples to wait for: it
// answers at once, and the clock still spaces its ticks 1.5 periods apart.
TEST(DeviceClock, AnInactiveDeviceTicksAtOneAndAHalfPeriods) {
  DeviceHandle h(std::make_unique<UdpDevice>(hapticloth::test::loopback_options()));
  const double t0 = mono_now();
  EXPECT_FALSE(h.await_sample(t0 + 1.0));
  EXPECT_LT(mono_now() - t0, 0.5);
  const DeviceClock clock(kPeriod);
  const double last = mono_now();
  const DeviceClock::Tick t = clock.wait(h, last);
  EXPECT_FALSE(t.sampled);
  EXPECT_GE(t.at - last, DeviceClock::kLatest * kPeriod - 1e-4);
  EXPECT_LT(t.at - last, DeviceClock::kLatest * kPeriod + kLateBound);
}

}  // namespace
