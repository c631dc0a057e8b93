// devices/udp: the wire codec, the UdpDevice over loopback against an in-process sender, and the
// real driver against the scripted fake rig (tools/fake_rig/hapticloth-fake-rig) as a
// subprocess. Every loop is bounded in iterations; no wall-clock time is asserted.

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

namespace {

namespace fs = std::filesystem;
using namespace hapticloth::devices;
using udp::ParseResult;
using Json = nlohmann::json;

const std::string kSourceDir = HAPTICLOTH_SOURCE_DIR;
const double kNaN = std::numeric_limits<double>::quiet_NaN();
const double kInf = std::numeric_limits<double>::infinity();

// --- codec -------------------------------------------------------------------------------------

udp::StatePacket sample_state(int fingers) {
  udp::StatePacket p;
  p.sequence = 0x0102030405060708ull;
  p.device_time = 12.345678901234;
  p.fingers = fingers;
  for (int i = 0; i < fingers; ++i) {
    p.finger[i].position = Vec3(0.01 * i - 0.02, -0.03 + 0.001 * i, 0.05);
    p.finger[i].velocity = Vec3(0.1, -0.2 * i, 1e-9);
    p.finger[i].buttons = 0x80000001u + i;
  }
  return p;
}

std::vector<std::uint8_t> encode(const udp::StatePacket& p) {
  std::vector<std::uint8_t> b(udp::kMaxStatePacketBytes);
  b.resize(udp::encode_state_packet(p, b.data(), b.size()));
  return b;
}

std::vector<std::uint8_t> encode(const udp::ForcePacket& p) {
  std::vector<std::uint8_t> b(udp::kMaxForcePacketBytes);
  b.resize(udp::encode_force_packet(p, b.data(), b.size()));
  return b;
}

ParseResult parse(const std::vector<std::uint8_t>& b, int fingers = 2, const Box& ws = Box{}) {
  udp::StatePacket out;
  return udp::parse_state_packet(b.data(), b.size(), fingers, ws, out);
}

void reseal(std::vector<std::uint8_t>& b) {  // recompute the CRC after an edit
  const std::uint32_t c = udp::crc32(b.data(), b.size() - 4);
  for (int i = 0; i < 4; ++i) b[b.size() - 4 + i] = static_cast<std::uint8_t>(c >> (8 * i));
}

TEST(UdpWire, Crc32IsZlibs) {
  const std::string check = "123456789";
  EXPECT_EQ(udp::crc32(reinterpret_cast<const std::uint8_t*>(check.data()), check.size()),
            0xCBF43926u);
  EXPECT_EQ(udp::crc32(nullptr, 0), 0u);
}

TEST(UdpWire, PacketSizesMatchTheSpec) {
  EXPECT_EQ(udp::state_packet_size(2), 132u);
  EXPECT_EQ(udp::force_packet_size(2), 84u);
  EXPECT_EQ(udp::state_packet_size(5), 24u + 52u * 5u + 4u);
  EXPECT_EQ(udp::force_packet_size(1), 32u + 24u + 4u);
}

TEST(UdpWire, StatePacketLayoutIsLittleEndianAtTheSpecOffsets) {
  const auto b = encode(sample_state(2));
  ASSERT_EQ(b.size(), 132u);
  EXPECT_EQ(std::string(b.begin(), b.begin() + 4), "HCST");
  EXPECT_EQ(b[4], 1);  // version, low byte first
  EXPECT_EQ(b[5], 0);
  EXPECT_EQ(b[6], 2);  // fingers
  EXPECT_EQ(b[7], 0);
  EXPECT_EQ(b[8], 0x08);  // sequence, low byte first
  EXPECT_EQ(b[15], 0x01);
  double x1 = 0;
  std::memcpy(&x1, b.data() + 24 + 52, 8);  // finger 1 position x (host is little-endian)
  EXPECT_EQ(x1, sample_state(2).finger[1].position.x());
  EXPECT_EQ(b[72 + 52], 0x02);  // finger 1 buttons 0x80000002
  EXPECT_EQ(b[75 + 52], 0x80);
}

TEST(UdpWire, StateRoundTripIsBitExact) {
  for (int n = 1; n <= kMaxFingers; ++n) {
    const auto p = sample_state(n);
    const auto b = encode(p);
    ASSERT_EQ(b.size(), udp::state_packet_size(n));
    udp::StatePacket q;
    ASSERT_EQ(udp::parse_state_packet(b.data(), b.size(), n, Box{}, q), ParseResult::Ok);
    EXPECT_EQ(q.sequence, p.sequence);
    EXPECT_EQ(q.device_time, p.device_time);
    EXPECT_EQ(q.fingers, n);
    for (int i = 0; i < n; ++i) {
      EXPECT_EQ(q.finger[i].position, p.finger[i].position);
      EXPECT_EQ(q.finger[i].velocity, p.finger[i].velocity);
      EXPECT_EQ(q.finger[i].buttons, p.finger[i].buttons);
    }
  }
}

TEST(UdpWire, ForceRoundTripIsBitExact) {
  udp::ForcePacket p;
  p.sequence = 77;
  p.server_time = 3.25;
  p.flags = kFlagClamped | kFlagStale;
  p.fingers = 3;
  p.force[0] = Vec3(1.5, -2.25, 0.1);
  p.force[2] = Vec3(-4.9999, 0, 1e-300);
  const auto b = encode(p);
  ASSERT_EQ(b.size(), 32u + 24u * 3u + 4u);
  EXPECT_EQ(std::string(b.begin(), b.begin() + 4), "HCFC");
  udp::ForcePacket q;
  ASSERT_EQ(udp::parse_force_packet(b.data(), b.size(), 3, q), ParseResult::Ok);
  EXPECT_EQ(q.sequence, 77u);
  EXPECT_EQ(q.server_time, 3.25);
  EXPECT_EQ(q.flags, p.flags);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(q.force[i], p.force[i]);
  ASSERT_EQ(udp::parse_force_packet(b.data(), b.size(), 0, q), ParseResult::Ok);  // any count
  EXPECT_EQ(udp::parse_force_packet(b.data(), b.size(), 2, q), ParseResult::Malformed);
}

TEST(UdpWire, EncodersRefuseBadFingerCountsAndSmallBuffers) {
  std::uint8_t buf[udp::kMaxStatePacketBytes];
  auto p = sample_state(2);
  EXPECT_EQ(udp::encode_state_packet(p, buf, 131), 0u);
  p.fingers = 0;
  EXPECT_EQ(udp::encode_state_packet(p, buf, sizeof buf), 0u);
  p.fingers = kMaxFingers + 1;
  EXPECT_EQ(udp::encode_state_packet(p, buf, sizeof buf), 0u);
  udp::ForcePacket f;
  f.fingers = 2;
  EXPECT_EQ(udp::encode_force_packet(f, buf, 83), 0u);
}

TEST(UdpWire, EveryTruncationAndExtensionIsMalformed) {
  const auto good = encode(sample_state(2));
  for (std::size_t n = 0; n < good.size(); ++n) {
    const std::vector<std::uint8_t> cut(good.begin(), good.begin() + n);
    EXPECT_EQ(parse(cut), ParseResult::Malformed) << "length " << n;
  }
  for (std::size_t extra = 1; extra <= 8; ++extra) {
    auto longer = good;
    longer.resize(good.size() + extra, 0);
    EXPECT_EQ(parse(longer), ParseResult::Malformed);
    reseal(longer);  // even with a CRC over the longer body
    EXPECT_EQ(parse(longer), ParseResult::Malformed);
  }
}

TEST(UdpWire, WrongMagicIsMalformed) {
  for (int i = 0; i < 4; ++i) {
    auto b = encode(sample_state(2));
    b[i] ^= 0x20;
    reseal(b);
    EXPECT_EQ(parse(b), ParseResult::Malformed);
  }
  // A force packet is not a state packet, and the other way round.
  udp::ForcePacket f;
  f.fingers = 2;
  EXPECT_EQ(parse(encode(f)), ParseResult::Malformed);
  udp::ForcePacket q;
  const auto s = encode(sample_state(2));
  EXPECT_EQ(udp::parse_force_packet(s.data(), s.size(), 2, q), ParseResult::Malformed);
}

TEST(UdpWire, AnySingleBitFlipIsRejected) {
  const auto good = encode(sample_state(2));
  for (std::size_t byte = 0; byte < good.size(); ++byte)
    for (int bit = 0; bit < 8; ++bit) {
      auto b = good;
      b[byte] ^= static_cast<std::uint8_t>(1u << bit);
      const ParseResult r = parse(b);
      // A flip in the version field is reported as a version problem, elsewhere malformed.
      if (byte == 4 || byte == 5)
        EXPECT_EQ(r, ParseResult::BadVersion) << byte << ":" << bit;
      else
        EXPECT_EQ(r, ParseResult::Malformed) << byte << ":" << bit;
    }
}

TEST(UdpWire, WrongVersionIsBadVersionWhateverTheSize) {
  for (std::uint16_t v : {0, 2, 256, 65535}) {
    auto b = encode(sample_state(2));
    b[4] = static_cast<std::uint8_t>(v);
    b[5] = static_cast<std::uint8_t>(v >> 8);
    reseal(b);
    EXPECT_EQ(parse(b), ParseResult::BadVersion) << v;
    b.resize(40);  // a future version may have another layout
    EXPECT_EQ(parse(b), ParseResult::BadVersion) << v;
  }
}

TEST(UdpWire, FingerCountMismatchIsMalformed) {
  EXPECT_EQ(parse(encode(sample_state(3)), 2), ParseResult::Malformed);
  EXPECT_EQ(parse(encode(sample_state(2)), 3), ParseResult::Malformed);
  EXPECT_EQ(parse(encode(sample_state(2)), 0), ParseResult::Malformed);
  for (int n : {0, 6, 255}) {  // outside 1..5, with a consistent size and CRC
    auto b = encode(sample_state(2));
    b[6] = static_cast<std::uint8_t>(n);
    b.resize(std::min<std::size_t>(udp::state_packet_size(n), 1500), 0);
    reseal(b);
    EXPECT_EQ(parse(b), ParseResult::Malformed) << n;
    EXPECT_EQ(parse(b, n), ParseResult::Malformed) << n;
  }
}

TEST(UdpWire, NonFiniteNumbersAreOutOfRange) {
  for (double bad : {kNaN, kInf, -kInf}) {
    for (int field = 0; field < 3; ++field) {
      auto p = sample_state(2);
      if (field == 0) p.device_time = bad;
      if (field == 1) p.finger[1].position.y() = bad;
      if (field == 2) p.finger[0].velocity.z() = bad;
      EXPECT_EQ(parse(encode(p)), ParseResult::OutOfRange) << field;
    }
  }
  udp::ForcePacket f;
  f.fingers = 2;
  f.force[1].x() = kNaN;
  const auto b = encode(f);
  udp::ForcePacket q;
  EXPECT_EQ(udp::parse_force_packet(b.data(), b.size(), 2, q), ParseResult::OutOfRange);
}

TEST(UdpWire, PositionOutsideTheWorkspaceIsOutOfRange) {
  Box ws;
  ws.min = Vec3(-0.1, -0.2, 0.0);
  ws.max = Vec3(0.1, 0.2, 0.3);
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side) {
      auto p = sample_state(2);
      p.finger[0].position = 0.5 * (ws.min + ws.max);
      p.finger[1].position = p.finger[0].position;
      p.finger[1].position[axis] = side ? ws.max[axis] : ws.min[axis];
      EXPECT_EQ(parse(encode(p), 2, ws), ParseResult::Ok) << "on the boundary";
      p.finger[1].position[axis] += side ? 1e-9 : -1e-9;
      EXPECT_EQ(parse(encode(p), 2, ws), ParseResult::OutOfRange) << axis << side;
    }
}

TEST(UdpWire, OutputIsUntouchedUnlessOk) {
  udp::StatePacket out = sample_state(1);
  auto p = sample_state(2);
  p.finger[1].position.x() = 5.0;
  EXPECT_EQ(udp::parse_state_packet(encode(p).data(), 132, 2, Box{}, out),
            ParseResult::OutOfRange);
  EXPECT_EQ(out.fingers, 1);
  EXPECT_EQ(udp::parse_state_packet(nullptr, 132, 2, Box{}, out), ParseResult::Malformed);
}

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

/// A UDP socket of the test, bound to 127.0.0.1 on a free port.
class LoopbackSocket {
 public:
  LoopbackSocket() {
    fd_ = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    EXPECT_EQ(::bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
    socklen_t len = sizeof a;
    ::getsockname(fd_, reinterpret_cast<sockaddr*>(&a), &len);
    port_ = ntohs(a.sin_port);
  }
  ~LoopbackSocket() { ::close(fd_); }
  std::uint16_t port() const { return port_; }
  void send_to(std::uint16_t port, const std::vector<std::uint8_t>& b) {
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = htons(port);
    ASSERT_EQ(::sendto(fd_, b.data(), b.size(), 0, reinterpret_cast<sockaddr*>(&a), sizeof a),
              static_cast<ssize_t>(b.size()));
  }
  /// Waits at most timeout_ms for one datagram; empty if none.
  std::vector<std::uint8_t> receive(int timeout_ms = 500) {
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, timeout_ms) != 1) return {};
    std::vector<std::uint8_t> b(2048);
    const ssize_t n = ::recv(fd_, b.data(), b.size(), 0);
    b.resize(n > 0 ? static_cast<std::size_t>(n) : 0);
    return b;
  }

 private:
  int fd_ = -1;
  std::uint16_t port_ = 0;
};

DeviceOptions loopback_options() {
  DeviceOptions opt;
  opt.driver = "udp";
  opt.udp_bind = "127.0.0.1:0";
  return opt;
}

double mono_now() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
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

// --- against the fake rig ----------------------------------------------------------------------

/// The fake rig as a subprocess; killed (by its pid) if it is still running at destruction.
class RigProcess {
 public:
  RigProcess(const std::vector<std::string>& args, const fs::path& dir) {
    const char* py = std::getenv("HAPTICLOTH_PYTHON");
    std::vector<std::string> argv{py && *py ? py : "/usr/bin/python3",
                                  kSourceDir + "/tools/fake_rig/hapticloth-fake-rig"};
    argv.insert(argv.end(), args.begin(), args.end());
    std::vector<char*> cargv;
    for (auto& a : argv) cargv.push_back(a.data());
    cargv.push_back(nullptr);
    stdout_ = (dir / "rig.out").string();
    stderr_ = (dir / "rig.err").string();
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 1, stdout_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&fa, 2, stderr_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (posix_spawn(&pid_, cargv[0], &fa, nullptr, cargv.data(), environ) != 0) pid_ = -1;
    posix_spawn_file_actions_destroy(&fa);
  }
  ~RigProcess() {
    if (running()) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, &status_, 0);
    }
  }
  bool started() const { return pid_ > 0; }
  bool running() {
    if (pid_ <= 0 || done_) return false;
    if (::waitpid(pid_, &status_, WNOHANG) == pid_) done_ = true;
    return !done_;
  }
  bool succeeded() const { return done_ && WIFEXITED(status_) && WEXITSTATUS(status_) == 0; }
  std::string output() const { return slurp(stdout_); }
  std::string errors() const { return slurp(stderr_); }

 private:
  static std::string slurp(const std::string& path) {
    std::ifstream in(path);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }
  pid_t pid_ = -1;
  int status_ = 0;
  bool done_ = false;
  std::string stdout_, stderr_;
};

/// A scratch directory removed at the end of the test.
struct ScratchDir {
  fs::path path;
  explicit ScratchDir(const std::string& name)
      : path(fs::temp_directory_path() /
             ("hapticloth_" + name + "_" + std::to_string(::getpid()))) {
    fs::create_directories(path);
  }
  ~ScratchDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

using Controller = std::function<DeviceCommand(const DeviceState&)>;

constexpr double kSpring = 30.0;  ///< N/m

/// The spring the loop renders: f = -k x per finger, clamped to 2 N.
DeviceCommand spring(const DeviceState& s) {
  DeviceCommand c;
  for (int i = 0; i < 2; ++i) {
    c.force[i] = -kSpring * s.finger[i].position;
    if (c.force[i].norm() > 2.0) {
      c.force[i] *= 2.0 / c.force[i].norm();
      c.flags |= kFlagClamped;
    }
  }
  return c;
}

struct LoopRun {
  std::vector<DeviceState> states;  ///< every Ok read
  Json summary;                     ///< the rig's JSON summary
  std::uint64_t allocations = 0;    ///< during read/write
  int ticks = 0;
};

/// Runs the device loop at 1 kHz (absolute deadlines) until the rig has exited, at most
/// max_ticks ticks, then reads once more and deactivates.
LoopRun run_against_rig(UdpDevice& dev, RigProcess& rig, const Controller& control,
                        int max_ticks = 12000) {
  LoopRun run;
  run.states.reserve(static_cast<std::size_t>(max_ticks));
  DeviceState state;
  DeviceCommand cmd;
  timespec next{};
  clock_gettime(CLOCK_MONOTONIC, &next);
  for (; run.ticks < max_ticks; ++run.ticks) {
    next.tv_nsec += 1000000;
    if (next.tv_nsec >= 1000000000) {
      next.tv_nsec -= 1000000000;
      ++next.tv_sec;
    }
    clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, nullptr);
    const double now = mono_now();
    hapticloth::test::AllocationGuard guard;
    const Status st = dev.read(now, state);
    if (state.received_time >= 0.0) cmd = control(state);
    dev.write(now, cmd);
    run.allocations += guard.count();
    if (st == Status::Ok) run.states.push_back(state);
    if (run.ticks % 20 == 0 && !rig.running()) break;
  }
  if (dev.read(mono_now(), state) == Status::Ok) run.states.push_back(state);
  dev.deactivate();
  EXPECT_FALSE(rig.running()) << "the rig did not finish within " << max_ticks << " ticks";
  EXPECT_TRUE(rig.succeeded()) << rig.errors();
  const std::string out = rig.output();
  const auto line = out.find('{');
  if (line != std::string::npos) run.summary = Json::parse(out.substr(line), nullptr, false);
  EXPECT_TRUE(run.summary.is_object()) << "rig output: " << out << "\n" << rig.errors();
  const auto& c = dev.counters();
  std::printf("rig: %s\ndevice: ticks %d samples %llu writes %llu malformed %llu version %llu "
              "duplicate %llu reordered %llu out_of_range %llu send_errors %llu\n",
              out.c_str(), run.ticks, static_cast<unsigned long long>(c.samples),
              static_cast<unsigned long long>(c.writes),
              static_cast<unsigned long long>(c.dropped_malformed),
              static_cast<unsigned long long>(c.dropped_version),
              static_cast<unsigned long long>(c.dropped_duplicate),
              static_cast<unsigned long long>(c.dropped_reordered),
              static_cast<unsigned long long>(c.dropped_out_of_range),
              static_cast<unsigned long long>(c.send_errors));
  return run;
}

struct ForceRow {
  double time = 0;
  std::uint64_t sequence = 0;
  std::uint32_t flags = 0;
  std::vector<double> f;
};

std::vector<ForceRow> load_force_log(const fs::path& path) {
  std::ifstream in(path);
  std::string line;
  std::vector<ForceRow> rows;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::stringstream ss(line);
    std::string cell;
    ForceRow r;
    std::getline(ss, cell, ',');
    r.time = std::strtod(cell.c_str(), nullptr);
    std::getline(ss, cell, ',');
    r.sequence = std::strtoull(cell.c_str(), nullptr, 10);
    std::getline(ss, cell, ',');
    r.flags = static_cast<std::uint32_t>(std::strtoul(cell.c_str(), nullptr, 10));
    while (std::getline(ss, cell, ',')) r.f.push_back(std::strtod(cell.c_str(), nullptr));
    rows.push_back(r);
  }
  return rows;
}

std::unique_ptr<UdpDevice> started_device(const std::string& record_path = "") {
  DeviceOptions opt = loopback_options();
  opt.record_path = record_path;
  auto dev = std::make_unique<UdpDevice>(opt);
  EXPECT_EQ(dev->configure(), "");
  EXPECT_EQ(dev->activate(), "");
  return dev;
}

std::string server_arg(const UdpDevice& dev) {
  return "127.0.0.1:" + std::to_string(dev.local_port());
}

/// Piecewise-linear interpolation, the rig's formula.
Vec3 lerp_knots(const std::vector<std::pair<double, Vec3>>& k, double t) {
  if (t <= k.front().first) return k.front().second;
  if (t >= k.back().first) return k.back().second;
  std::size_t i = 1;
  while (k[i].first <= t) ++i;
  const auto& [t0, p0] = k[i - 1];
  const auto& [t1, p1] = k[i];
  const double s = (t - t0) / (t1 - t0);
  Vec3 p;
  for (int a = 0; a < 3; ++a) p[a] = p0[a] + s * (p1[a] - p0[a]);
  return p;
}

TEST(UdpFakeRig, CleanRunFollowsTheTrajectoryAndEchoesForces) {
  ScratchDir dir("udp_clean");
  const std::vector<std::vector<std::pair<double, Vec3>>> knots = {
      {{0.0, Vec3(-0.05, 0.0, 0.0)}, {0.5, Vec3(-0.02, 0.03, 0.01)}, {1.5, Vec3(0.04, -0.01, 0.0)}},
      {{0.0, Vec3(0.05, 0.0, 0.0)}, {1.0, Vec3(0.01, 0.02, -0.03)}}};
  {
    std::ofstream tr(dir.path / "trajectory.csv");
    tr << "time,finger,x,y,z\n";
    tr.precision(17);
    for (std::size_t f = 0; f < knots.size(); ++f)
      for (const auto& [t, p] : knots[f])
        tr << t << "," << f << "," << p.x() << "," << p.y() << "," << p.z() << "\n";
  }
  const fs::path device_log = dir.path / "device.csv";
  auto dev = started_device(device_log.string());
  RigProcess rig({"--server", server_arg(*dev), "--duration", "1.5", "--trajectory",
                  (dir.path / "trajectory.csv").string(), "--log",
                  (dir.path / "forces.csv").string()},
                 dir.path);
  ASSERT_TRUE(rig.started());
  const LoopRun run = run_against_rig(*dev, rig, spring);
  ASSERT_TRUE(run.summary.is_object());
  const Json& s = run.summary;
  const auto& c = dev->counters();

  // Every datagram is accounted for; nothing is dropped in a clean run.
  const std::uint64_t sent = s["sent"], valid = s["valid"];
  EXPECT_EQ(valid, s["sequences"].get<std::uint64_t>());
  EXPECT_GE(valid, 1400u);
  EXPECT_LE(sent - (c.samples + c.dropped_total()), sent / 100) << "lost in the kernel";
  EXPECT_EQ(c.dropped_total(), 0u);
  EXPECT_LE(c.samples, valid);
  EXPECT_EQ(run.allocations, 0u);

  // States: the trajectory at the rig's time, sequences increasing.
  ASSERT_GT(run.states.size(), 100u);
  std::uint64_t prev = 0;
  for (const auto& st : run.states) {
    EXPECT_GT(st.sequence, prev);
    prev = st.sequence;
    EXPECT_NEAR(st.device_time, 0.001 * static_cast<double>(st.sequence - 1), 1e-12);
    for (int f = 0; f < 2; ++f) {
      EXPECT_LT((st.finger[f].position - lerp_knots(knots[f], st.device_time)).norm(), 1e-12);
      if (st.sequence > 1) {  // backward difference over one tick
        const Vec3 v = (lerp_knots(knots[f], st.device_time) -
                        lerp_knots(knots[f], st.device_time - 0.001)) / 0.001;
        EXPECT_LT((st.finger[f].velocity - v).norm(), 1e-6);
      }
    }
  }

  // Forces: finite, echo sequences the rig sent, and are the spring of that sample.
  EXPECT_EQ(s["forces_nonfinite"], 0);
  EXPECT_EQ(s["forces_malformed"], 0);
  EXPECT_EQ(s["forces_unknown_sequence"], 0);
  EXPECT_EQ(s["forces_fault"], 0);
  const std::uint64_t forces = s["forces_received"];
  EXPECT_GE(forces, c.samples / 2);
  EXPECT_LE(forces, c.writes);
  const auto rows = load_force_log(dir.path / "forces.csv");
  ASSERT_EQ(rows.size(), forces);
  std::uint64_t last = 0;
  for (const auto& r : rows) {
    ASSERT_EQ(r.f.size(), 6u);
    EXPECT_GE(r.sequence, last);
    last = r.sequence;
    const double t = 0.001 * static_cast<double>(r.sequence - 1);
    for (int f = 0; f < 2; ++f) {
      const Vec3 expected = -kSpring * lerp_knots(knots[f], t);  // |f| <= 30 * 0.05 < 2 N
      EXPECT_LT((Vec3(r.f[3 * f], r.f[3 * f + 1], r.f[3 * f + 2]) - expected).norm(), 1e-9);
    }
  }

  // The device log: one row per sample per finger, with the force sent in reply (the spring,
  // or zero for a sample answered only by the zero-force packet of deactivate).
  const auto log = load_device_log(device_log.string());
  EXPECT_EQ(log.size(), 2 * run.states.size());
  for (std::size_t i = 0; i < log.size(); ++i) {
    const auto& r = log[i];
    EXPECT_EQ(r.finger, static_cast<int>(i % 2));
    const bool last = i + 2 >= log.size();
    EXPECT_TRUE((r.f + kSpring * r.x).norm() < 1e-6 || (last && r.f == Vec3::Zero())) << r.time;
  }
}

TEST(UdpFakeRig, FaultInjectionMatchesTheCounters) {
  ScratchDir dir("udp_faults");
  auto dev = started_device();
  RigProcess rig({"--server", server_arg(*dev), "--duration", "1.5", "--seed", "7", "--loss",
                  "0.10", "--reorder", "0.05", "--duplicate", "0.05", "--garbage", "0.05",
                  "--log", (dir.path / "forces.csv").string()},
                 dir.path);
  ASSERT_TRUE(rig.started());
  const LoopRun run = run_against_rig(*dev, rig, spring);
  ASSERT_TRUE(run.summary.is_object());
  const Json& s = run.summary;
  const Json& g = s["garbage"];
  const auto& c = dev->counters();
  const std::uint64_t sent = s["sent"], valid = s["valid"], reordered = s["reordered"],
                      duplicated = s["duplicated"], lost = s["lost"],
                      sequences = s["sequences"];
  const std::uint64_t malformed = g["random"].get<std::uint64_t>() + g["truncated"].get<int>() +
                                  g["long"].get<int>() + g["magic"].get<int>() +
                                  g["crc"].get<int>() + g["fingers"].get<int>();
  const std::uint64_t version = g["version"], range = g["range"].get<int>() + g["nan"].get<int>();
  EXPECT_EQ(valid + lost + s["garbage_total"].get<std::uint64_t>(), sequences);
  EXPECT_EQ(sent, valid + duplicated + s["garbage_total"].get<std::uint64_t>());
  // The faults happened at about the rates asked for (seeded: the same numbers every run).
  EXPECT_NEAR(static_cast<double>(lost) / sequences, 0.10, 0.03);
  EXPECT_GT(reordered, 0u);
  EXPECT_GT(duplicated, 0u);
  EXPECT_GT(malformed, 0u);
  EXPECT_GT(version, 0u);
  EXPECT_GT(range, 0u);

  // Exact when the kernel delivered every datagram (loopback, a 1 MB socket buffer); otherwise
  // the counters can only be lower.
  const std::uint64_t accounted = c.samples + c.dropped_total();
  EXPECT_LE(sent - accounted, sent / 100) << "lost in the kernel";
  if (accounted == sent) {
    EXPECT_EQ(c.samples, valid - reordered);
    EXPECT_EQ(c.dropped_reordered, reordered);
    EXPECT_EQ(c.dropped_duplicate, duplicated);
    EXPECT_EQ(c.dropped_malformed, malformed);
    EXPECT_EQ(c.dropped_version, version);
    EXPECT_EQ(c.dropped_out_of_range, range);
  } else {
    EXPECT_LE(c.samples, valid - reordered);
    EXPECT_LE(c.dropped_reordered, reordered);
    EXPECT_LE(c.dropped_duplicate, duplicated);
    EXPECT_LE(c.dropped_malformed, malformed);
    EXPECT_LE(c.dropped_version, version);
    EXPECT_LE(c.dropped_out_of_range, range);
  }
  EXPECT_EQ(run.allocations, 0u);

  // The forces: finite, echoing sequences the rig sent validly, the spring at the still points.
  EXPECT_EQ(s["forces_nonfinite"], 0);
  EXPECT_EQ(s["forces_malformed"], 0);
  EXPECT_EQ(s["forces_unknown_sequence"], 0);
  EXPECT_GE(s["forces_received"].get<std::uint64_t>(), c.samples / 2);
  const auto rows = load_force_log(dir.path / "forces.csv");
  ASSERT_FALSE(rows.empty());
  for (const auto& r : rows) {
    ASSERT_EQ(r.f.size(), 6u);
    EXPECT_EQ(r.f[0], -kSpring * -0.02);
    EXPECT_EQ(r.f[3], -kSpring * 0.02);
    EXPECT_EQ(r.f[1], 0.0);
    EXPECT_EQ(r.flags, 0u);
  }
}

TEST(UdpFakeRig, NanForceReachesTheRigAsZeroWithTheFaultFlag) {
  ScratchDir dir("udp_nan");
  auto dev = started_device();
  RigProcess rig({"--server", server_arg(*dev), "--duration", "0.5", "--log",
                  (dir.path / "forces.csv").string()},
                 dir.path);
  ASSERT_TRUE(rig.started());
  const LoopRun run = run_against_rig(*dev, rig, [](const DeviceState& st) {
    DeviceCommand c = spring(st);
    c.force[0].y() = kNaN;  // finger 0 broken, finger 1 fine
    return c;
  });
  ASSERT_TRUE(run.summary.is_object());
  const Json& s = run.summary;
  const std::uint64_t forces = s["forces_received"];
  ASSERT_GT(forces, 0u);
  EXPECT_EQ(s["forces_nonfinite"], 0);
  EXPECT_EQ(s["forces_fault"].get<std::uint64_t>(), forces);
  const auto rows = load_force_log(dir.path / "forces.csv");
  ASSERT_EQ(rows.size(), forces);
  for (const auto& r : rows) {
    ASSERT_EQ(r.f.size(), 6u);
    EXPECT_EQ(r.flags & kFlagFault, kFlagFault);
    EXPECT_EQ(r.f[3], -kSpring * 0.02);
    EXPECT_EQ(r.f[0], 0.0);
    EXPECT_EQ(r.f[1], 0.0);
    EXPECT_EQ(r.f[2], 0.0);
  }
}

}  // namespace
