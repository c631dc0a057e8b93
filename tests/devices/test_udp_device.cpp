// devices/udp/udp_device: the endpoint, the lifecycle and the UdpDevice over loopback against an
// in-process sender (drop rules, newest sample, no allocation). Every loop is bounded.

#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "log/device_log.hpp"
#include "support/alloc_counter.hpp"
#include "udp/udp_device.hpp"
#include "udp/wire.hpp"
#include "hal/mono_clock.hpp"
#include "support/loopback_socket.hpp"
#include "support/udp_packets.hpp"

namespace {

namespace fs = std::filesystem;
using namespace hapticloth::devices;
using udp::ParseResult;
using hapticloth::test::encode;
using hapticloth::test::reseal;
using hapticloth::test::loopback_options;
using hapticloth::test::sample_state;
using hapticloth::test::LoopbackSocket;

const double kNaN = std::numeric_limits<double>::quiet_NaN();
const double kInf = std::numeric_limits<double>::infinity();

// --- endpoint and lifecycle --------------------------------------------------------------------

TEST(UdpEndpoint, ParsesHostPort) {
  UdpEndpoint e;
  EXPECT_EQ(parse_udp_endpoint("127.0.0.1:47800", e), "");
  EXPECT_EQ(e.address, 0x7F000001u);
  EXPECT_EQ(e.port, 47800);
  EXPECT_EQ(parse_udp_endpoint("localhost:1", e), "");
  EXPECT_EQ(e.address, 0x7F000001u);
  EXPECT_EQ(parse_udp_endpoint("0.0.0.0:0", e), "");
  EXPECT_EQ(e.port, 0);
  for (const char* bad : {"", "127.0.0.1", "127.0.0.1:", ":80", "example.org:80", "1.2.3:80",
                          "1.2.3.4:65536", "1.2.3.4:-1", "1.2.3.4:8x", "1.2.3.4:123456",
                          "[::1]:80"}) {
    const std::string err = parse_udp_endpoint(bad, e);
    EXPECT_NE(err.find("udp_bind"), std::string::npos) << bad << ": " << err;
  }
}

TEST(UdpDevice, FactoryRejectsABadBindNamingTheField) {
  DeviceOptions opt;
  opt.driver = "udp";
  opt.udp_bind = "127.0.0.1:http";
  try {
    make_udp_device(opt);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("udp_bind"), std::string::npos) << e.what();
  }
  opt.udp_bind = "127.0.0.1:0";
  opt.fingers = 6;
  EXPECT_THROW(make_udp_device(opt), std::invalid_argument);
}

/// Reads until `datagrams` have been accounted for (taken or dropped), at most 500 tries 1 ms
/// apart. Returns whether any read returned Ok; the newest state goes to `state`.
bool read_until(UdpDevice& dev, std::uint64_t datagrams, DeviceState& state) {
  bool ok = false;
  for (int i = 0; i < 500; ++i) {
    ok |= dev.read(mono_now(), state) == Status::Ok;
    const auto& c = dev.counters();
    if (c.samples + c.dropped_total() >= datagrams) break;
    ::usleep(1000);
  }
  return ok;
}

TEST(UdpDevice, ConfigureReportsAPortInUse) {
  LoopbackSocket taken;
  DeviceOptions opt = loopback_options();
  opt.udp_bind = "127.0.0.1:" + std::to_string(taken.port());
  UdpDevice dev(opt);
  const std::string err = dev.configure();
  EXPECT_NE(err.find("bind"), std::string::npos) << err;
  DeviceState s;
  EXPECT_EQ(dev.read(1.0, s), Status::Error);
  EXPECT_EQ(dev.write(1.0, DeviceCommand{}), Status::Error);
}

TEST(UdpDevice, CountsEveryDropRuleAndKeepsTheNewestSample) {
  UdpDevice dev(loopback_options());
  ASSERT_EQ(dev.configure(), "");
  ASSERT_EQ(dev.activate(), "");
  ASSERT_NE(dev.local_port(), 0);
  LoopbackSocket rig;
  DeviceState state;
  EXPECT_EQ(dev.read(0.5, state), Status::NoData);
  EXPECT_EQ(dev.write(0.5, DeviceCommand{}), Status::NoData) << "no peer yet";

  auto p = sample_state(2);
  auto at = [&](std::uint64_t seq) {
    p.sequence = seq;
    p.device_time = 0.001 * static_cast<double>(seq);
    return encode(p);
  };
  auto bad_version = at(9);
  bad_version[4] = 2;
  reseal(bad_version);
  auto out_of_range = at(9);
  p.finger[0].position.x() = 1.0;
  out_of_range = encode(p);
  p = sample_state(2);
  auto bad_crc = at(9);
  bad_crc[131] ^= 1;

  std::uint64_t sent = 0;
  for (const auto& d : {at(5), at(5), at(3), at(7), at(6), bad_version, out_of_range, bad_crc,
                        encode(sample_state(3)), std::vector<std::uint8_t>{},
                        std::vector<std::uint8_t>(3000, 0x48), at(8)}) {
    rig.send_to(dev.local_port(), d);
    ++sent;
  }
  ASSERT_TRUE(read_until(dev, sent, state));
  const auto& c = dev.counters();
  EXPECT_EQ(c.samples, 3u);            // 5, 7, 8
  EXPECT_EQ(c.dropped_duplicate, 1u);  // 5 again
  EXPECT_EQ(c.dropped_reordered, 2u);  // 3 after 5, 6 after 7
  EXPECT_EQ(c.dropped_version, 1u);
  EXPECT_EQ(c.dropped_out_of_range, 1u);
  EXPECT_EQ(c.dropped_malformed, 4u);  // CRC, 3 fingers, empty, oversized
  EXPECT_EQ(state.sequence, 8u);
  EXPECT_DOUBLE_EQ(state.device_time, 0.008);
  EXPECT_EQ(state.finger[1].position, p.finger[1].position);
  EXPECT_EQ(state.finger[1].buttons, p.finger[1].buttons);
  EXPECT_EQ(state.finger[2].position, Vec3::Zero());
  EXPECT_GT(state.received_time, 0.0);

  // Nothing new: NoData and the state is left alone.
  DeviceState untouched;
  untouched.sequence = 1234;
  EXPECT_EQ(dev.read(2.0, untouched), Status::NoData);
  EXPECT_EQ(untouched.sequence, 1234u);

  // The reply goes to the sender and echoes the newest sequence.
  DeviceCommand cmd;
  cmd.force[0] = Vec3(0.5, -1.0, 2.0);
  cmd.force[1] = Vec3(-3.0, 0.0, 1e-3);
  cmd.flags = kFlagClamped;
  ASSERT_EQ(dev.write(2.5, cmd), Status::Ok);
  const auto reply = rig.receive();
  udp::ForcePacket f;
  ASSERT_EQ(udp::parse_force_packet(reply.data(), reply.size(), 2, f), ParseResult::Ok);
  EXPECT_EQ(f.sequence, 8u);
  EXPECT_EQ(f.server_time, 2.5);
  EXPECT_EQ(f.flags, kFlagClamped);
  EXPECT_EQ(f.force[0], cmd.force[0]);
  EXPECT_EQ(f.force[1], cmd.force[1]);
  EXPECT_EQ(dev.counters().writes, 1u);
  EXPECT_EQ(dev.counters().send_errors, 0u);

  // Deactivate sends one zero-force packet and closes the socket.
  dev.deactivate();
  const auto last = rig.receive();
  ASSERT_EQ(udp::parse_force_packet(last.data(), last.size(), 2, f), ParseResult::Ok);
  EXPECT_EQ(f.force[0], Vec3::Zero());
  EXPECT_EQ(f.force[1], Vec3::Zero());
  EXPECT_EQ(dev.read(3.0, state), Status::Error);
}

TEST(UdpDevice, NonFiniteForceIsSentAsZeroWithTheFaultFlag) {
  UdpDevice dev(loopback_options());
  ASSERT_EQ(dev.configure(), "");
  ASSERT_EQ(dev.activate(), "");
  LoopbackSocket rig;
  rig.send_to(dev.local_port(), encode(sample_state(2)));
  DeviceState state;
  ASSERT_TRUE(read_until(dev, 1, state));
  for (double bad : {kNaN, kInf}) {
    DeviceCommand cmd;
    cmd.force[0] = Vec3(1.0, bad, 0.0);
    cmd.force[1] = Vec3(0.25, 0.5, -0.75);
    cmd.flags = kFlagStale;
    ASSERT_EQ(dev.write(1.0, cmd), Status::Ok);
    const auto reply = rig.receive();
    udp::ForcePacket f;
    ASSERT_EQ(udp::parse_force_packet(reply.data(), reply.size(), 2, f), ParseResult::Ok);
    EXPECT_EQ(f.force[0], Vec3::Zero());
    EXPECT_EQ(f.force[1], cmd.force[1]);
    EXPECT_EQ(f.flags, kFlagStale | kFlagFault);
  }
}

TEST(UdpDevice, ReadAndWriteDoNotAllocate) {
  DeviceOptions opt = loopback_options();
  opt.record_path = (fs::temp_directory_path() / ("udp_alloc_" + std::to_string(::getpid()) +
                                                  ".csv")).string();
  UdpDevice dev(opt);
  ASSERT_EQ(dev.configure(), "");
  ASSERT_EQ(dev.activate(), "");
  LoopbackSocket rig;
  std::vector<std::vector<std::uint8_t>> packets;
  for (std::uint64_t s = 1; s <= 50; ++s) {
    auto p = sample_state(2);
    p.sequence = s;
    packets.push_back(encode(p));
  }
  packets.push_back({1, 2, 3});
  DeviceState state;
  DeviceCommand cmd;
  cmd.force[0] = Vec3(0.1, 0.2, 0.3);
  std::uint64_t allocations = 0;
  for (const auto& b : packets) {
    rig.send_to(dev.local_port(), b);
    hapticloth::test::AllocationGuard guard;
    dev.read(1.0, state);
    dev.write(1.0, cmd);
    allocations += guard.count();
  }
  EXPECT_EQ(allocations, 0u);
  dev.deactivate();
  fs::remove(opt.record_path);
}

}  // namespace

// --- one rig per session, and only fresh samples (issue 36 items 2 and 3) -------------------

namespace {
/// Sends one state packet (sequence `seq`, device_time `t`) from `rig`, waits (bounded) for it
/// to arrive and reads it at loop time `now`.
Status send_and_read(UdpDevice& dev, LoopbackSocket& rig, std::uint64_t seq, double t, double now,
                     DeviceState& state) {
  auto p = sample_state(2);
  p.sequence = seq;
  p.device_time = t;
  rig.send_to(dev.local_port(), encode(p));
  if (!dev.await_sample(mono_now() + 1.0)) return Status::Error;
  return dev.read(now, state);
}
}  // namespace

// A rig that streams before the session (while the cloth settles): what the socket queued is
// discarded at activate and counted, and the first sample read is the one sent after it.
TEST(UdpDevice, ActivateDiscardsWhatWasQueuedBeforeTheSession) {
  UdpDevice dev(loopback_options());
  ASSERT_EQ(dev.configure(), "");
  LoopbackSocket rig;
  for (std::uint64_t s = 1; s <= 300; ++s) {  // more than one read takes (256)
    auto p = sample_state(2);
    p.sequence = s;
    p.device_time = 0.001 * static_cast<double>(s);
    rig.send_to(dev.local_port(), encode(p));
  }
  ::usleep(20000);  // loopback delivers at once; leave it time all the same
  ASSERT_EQ(dev.activate(), "");
  EXPECT_EQ(dev.counters().dropped_backlog, 300u);
  DeviceState state;
  EXPECT_EQ(dev.read(1.0, state), Status::NoData);
  ASSERT_EQ(send_and_read(dev, rig, 301, 0.301, 1.0, state), Status::Ok);
  EXPECT_EQ(state.sequence, 301u);
  EXPECT_EQ(dev.counters().samples, 1u);
}

// A sample that waited longer than the watchdog (5 ms), by the rig's clock, is dropped as stale:
// the state keeps the last fresh sample, and the safety gate sees it age. Fresh ones are taken,
// a clock that runs slow within 1000 ppm is followed, and a clock that jumped back is taken
// afresh after 1 s of stale samples.
TEST(UdpDevice, ASampleOlderThanTheWatchdogIsStale) {
  UdpDevice dev(loopback_options());  // stale_after 5 ms
  ASSERT_EQ(dev.configure(), "");
  ASSERT_EQ(dev.activate(), "");
  LoopbackSocket rig;
  DeviceState state;
  // Rig clock = loop clock - 10 s, packets taken 0.2 ms after they were sent.
  ASSERT_EQ(send_and_read(dev, rig, 1, 0.0000, 10.0002, state), Status::Ok);
  ASSERT_EQ(send_and_read(dev, rig, 2, 0.0010, 10.0011, state), Status::Ok);  // waited less: fresh
  // Sent at 2 ms, read 8 ms later (a queue behind a stalled loop): stale, dropped.
  EXPECT_EQ(send_and_read(dev, rig, 3, 0.0020, 10.0100, state), Status::NoData);
  EXPECT_EQ(dev.counters().dropped_stale, 1u);
  EXPECT_EQ(state.sequence, 2u);
  // The reply echoes the sample its force is of, not the stale one.
  ASSERT_EQ(dev.write(10.0101, DeviceCommand{}), Status::Ok);
  udp::ForcePacket f;
  const auto reply = rig.receive();
  ASSERT_EQ(udp::parse_force_packet(reply.data(), reply.size(), 2, f), ParseResult::Ok);
  EXPECT_EQ(f.sequence, 2u);
  // 4 ms late is within the watchdog.
  ASSERT_EQ(send_and_read(dev, rig, 4, 0.0100, 10.0141, state), Status::Ok);
  // A rig clock running 500 ppm slow for 10 s: 5 ms behind, and still fresh.
  ASSERT_EQ(send_and_read(dev, rig, 5, 9.9950, 20.0000, state), Status::Ok);
  EXPECT_EQ(dev.counters().dropped_stale, 1u);
  // The rig's clock jumps back 1 minute: stale until 1 s has passed with nothing taken.
  EXPECT_EQ(send_and_read(dev, rig, 6, -50.0, 20.001, state), Status::NoData);
  EXPECT_EQ(send_and_read(dev, rig, 7, -49.5, 20.501, state), Status::NoData);
  EXPECT_EQ(dev.counters().dropped_stale, 3u);
  ASSERT_EQ(send_and_read(dev, rig, 8, -48.99, 21.01, state), Status::Ok);
  ASSERT_EQ(send_and_read(dev, rig, 9, -48.989, 21.0111, state), Status::Ok);
  EXPECT_EQ(state.sequence, 9u);
}

// Two rigs sending to one port: the session is the first rig's. The second one's packets are
// counted as from another sender and never taken, even with higher sequences, and the forces go
// to the first; a new session (activate) takes whichever rig sends first.
TEST(UdpDevice, TheSessionKeepsTheFirstRigAndCountsAnotherSender) {
  UdpDevice dev(loopback_options());
  ASSERT_EQ(dev.configure(), "");
  ASSERT_EQ(dev.activate(), "");
  LoopbackSocket first, second;
  DeviceState state;
  ASSERT_EQ(send_and_read(dev, first, 1, 0.001, 5.0, state), Status::Ok);
  EXPECT_EQ(send_and_read(dev, second, 1000, 0.002, 5.001, state), Status::NoData);
  EXPECT_EQ(send_and_read(dev, second, 1001, 0.003, 5.002, state), Status::NoData);
  ASSERT_EQ(send_and_read(dev, first, 2, 0.004, 5.003, state), Status::Ok);
  EXPECT_EQ(state.sequence, 2u);
  EXPECT_EQ(dev.counters().dropped_other_sender, 2u);
  EXPECT_EQ(dev.counters().dropped_reordered, 0u);
  ASSERT_EQ(dev.write(5.003, DeviceCommand{}), Status::Ok);
  udp::ForcePacket f;
  const auto reply = first.receive();
  ASSERT_EQ(udp::parse_force_packet(reply.data(), reply.size(), 2, f), ParseResult::Ok);
  EXPECT_EQ(f.sequence, 2u);

  dev.deactivate();
  (void)first.receive();  // the zero-force packet
  ASSERT_EQ(dev.activate(), "");
  ASSERT_EQ(send_and_read(dev, second, 1, 0.010, 6.0, state), Status::Ok);
  EXPECT_EQ(send_and_read(dev, first, 3, 0.011, 6.001, state), Status::NoData);
  EXPECT_EQ(dev.counters().dropped_other_sender, 3u);
}
