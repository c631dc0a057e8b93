// devices/composite/composite_device: a device made of one-finger UDP parts, over loopback. A
// part not heard from yet, or silent past its own watchdog, marks its finger absent
// (DeviceState::absent): its position means nothing (a part not yet heard reads as the device
// origin, which may be inside the cloth). Every loop is bounded.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "composite/composite_device.hpp"
#include "support/loopback_socket.hpp"
#include "support/udp_packets.hpp"

namespace {

using namespace hapticloth::devices;
using hapticloth::test::encode;
using hapticloth::test::LoopbackSocket;
using hapticloth::test::sample_state;

std::uint16_t free_port() {
  LoopbackSocket s;  // bound to a free port, released when it closes
  return s.port();
}

// Reads until the device takes a sample at loop time `now` (at most 2 s of polling: a safety
// limit, the datagrams are on loopback).
bool read_sample(CompositeDevice& dev, double now, DeviceState& state) {
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(2);
  while (std::chrono::steady_clock::now() < give_up) {
    if (dev.read(now, state) == Status::Ok) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return false;
}

TEST(CompositeDevice, AFingerIsAbsentUntilItsPartIsHeardAndAfterItFallsSilent) {
  const std::uint16_t ports[2] = {free_port(), free_port()};
  DeviceOptions opt;
  opt.stale_after = 0.05;
  for (std::uint16_t port : ports) {
    DeviceOptions part;
    part.driver = "udp";
    part.udp_bind = "127.0.0.1:" + std::to_string(port);
    opt.parts.push_back(part);
  }
  CompositeDevice dev(opt);
  ASSERT_EQ(dev.configure(), "");
  ASSERT_EQ(dev.activate(), "");
  LoopbackSocket rig0, rig1;
  auto packet = [](std::uint64_t seq, double rig_time) {  // the rig's clock keeps the loop's pace
    auto p = sample_state(1);
    p.sequence = seq;
    p.device_time = rig_time;
    return encode(p);
  };
  DeviceState state;
  rig0.send_to(ports[0], packet(1, 1.0));  // only part 0 has spoken
  ASSERT_TRUE(read_sample(dev, 1.0, state));
  EXPECT_EQ(state.absent, 0b10u);
  rig1.send_to(ports[1], packet(1, 1.01));  // now both
  ASSERT_TRUE(read_sample(dev, 1.01, state));
  EXPECT_EQ(state.absent, 0u);
  rig0.send_to(ports[0], packet(2, 1.2));  // part 1 silent past its 50 ms watchdog
  ASSERT_TRUE(read_sample(dev, 1.2, state));
  EXPECT_EQ(state.absent, 0b10u);
  dev.deactivate();
}

}  // namespace
