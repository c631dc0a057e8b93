// devices/udp/wire: the UDP device protocol's codec (proto/udp_device.md): layout, round trips,
// and every malformed, wrong-version and out-of-range packet rejected.

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
#include "support/udp_packets.hpp"

namespace {

using namespace hapticloth::devices;
using udp::ParseResult;
using hapticloth::test::encode;
using hapticloth::test::reseal;
using hapticloth::test::sample_state;

const double kNaN = std::numeric_limits<double>::quiet_NaN();
const double kInf = std::numeric_limits<double>::infinity();

// --- codec -------------------------------------------------------------------------------------

ParseResult parse(const std::vector<std::uint8_t>& b, int fingers = 2, const Box& ws = Box{}) {
  udp::StatePacket out;
  return udp::parse_state_packet(b.data(), b.size(), fingers, ws, out);
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

}  // namespace

// --- the tactile packet ------------------------------------------------------------------------

namespace {

udp::TactilePacket sample_tactile() {
  udp::TactilePacket p;
  p.sequence = 0x0102030405060708ull;
  p.server_time = 12.5;
  p.flags = kTactileClamped;
  p.sample_rate = 4000;
  p.fingers = 2;
  p.samples = 4;
  p.rows = 6;
  p.cols = 4;
  for (int f = 0; f < 2; ++f) {
    TactileFrame& fr = p.frames.finger[f];
    fr.samples = 4;
    fr.rows = 6;
    fr.cols = 4;
    for (int k = 0; k < 4; ++k) fr.vibration[k] = 1e-6f * static_cast<float>(k + 10 * f) - 2e-6f;
    for (int k = 0; k < 24; ++k) fr.pins[k] = 1e-5f * static_cast<float>(k) + 1e-3f * static_cast<float>(f);
  }
  return p;
}

std::vector<std::uint8_t> encode_tactile(const udp::TactilePacket& p) {
  std::vector<std::uint8_t> b(udp::kMaxTactilePacketBytes);
  b.resize(udp::encode_tactile_packet(p, b.data(), b.size()));
  return b;
}

ParseResult parse_tactile(const std::vector<std::uint8_t>& b, int fingers = 2) {
  udp::TactilePacket out;
  return udp::parse_tactile_packet(b.data(), b.size(), fingers, out);
}

}  // namespace

// 32 + 4 n (samples + pins) + 4 bytes: 260 for two fingers of 4 samples and 24 pins; the fields
// at the spec's offsets, little-endian; a round trip gives every value back bit for bit.
TEST(UdpWire, TactilePacketLayoutAndRoundTrip) {
  const udp::TactilePacket p = sample_tactile();
  const std::vector<std::uint8_t> b = encode_tactile(p);
  ASSERT_EQ(b.size(), 260u);
  EXPECT_EQ(std::memcmp(b.data(), "HCTA", 4), 0);
  EXPECT_EQ(b[4] | (b[5] << 8), 1);   // version
  EXPECT_EQ(b[6], 2);                  // fingers
  EXPECT_EQ(b[7], 4);                  // samples
  EXPECT_EQ(b[8], 0x08);               // sequence, little-endian
  EXPECT_EQ(b[28] | (b[29] << 8), 4000);  // sample rate
  EXPECT_EQ(b[30], 6);
  EXPECT_EQ(b[31], 4);
  float v0;
  std::memcpy(&v0, b.data() + 32, 4);
  EXPECT_EQ(v0, p.frames.finger[0].vibration[0]);
  float pin1_23;  // finger 1's last pin: after finger 0's 28 values and finger 1's 4 samples
  std::memcpy(&pin1_23, b.data() + 32 + 4 * (28 + 4 + 23), 4);
  EXPECT_EQ(pin1_23, p.frames.finger[1].pins[23]);
  udp::TactilePacket q;
  ASSERT_EQ(udp::parse_tactile_packet(b.data(), b.size(), 2, q), ParseResult::Ok);
  EXPECT_EQ(q.sequence, p.sequence);
  EXPECT_EQ(q.server_time, p.server_time);
  EXPECT_EQ(q.flags, p.flags);
  EXPECT_EQ(q.sample_rate, 4000);
  for (int f = 0; f < 2; ++f) {
    for (int k = 0; k < 4; ++k) EXPECT_EQ(q.frames.finger[f].vibration[k], p.frames.finger[f].vibration[k]);
    for (int k = 0; k < 24; ++k) EXPECT_EQ(q.frames.finger[f].pins[k], p.frames.finger[f].pins[k]);
  }
  EXPECT_EQ(encode_tactile(q), b);
}

// Every truncation and extension, every single bit flip, another version, a non-finite sample, a
// layout past the frame's room and another finger count are rejected, each with its result;
// the encoder refuses what it cannot write.
TEST(UdpWire, TactilePacketRejectsWhatIsNotOne) {
  const std::vector<std::uint8_t> good = encode_tactile(sample_tactile());
  for (std::size_t n = 0; n < good.size(); ++n)
    EXPECT_EQ(parse_tactile(std::vector<std::uint8_t>(good.begin(), good.begin() + static_cast<long>(n))),
              ParseResult::Malformed);
  std::vector<std::uint8_t> longer = good;
  longer.push_back(0);
  EXPECT_EQ(parse_tactile(longer), ParseResult::Malformed);
  for (std::size_t i = 0; i < good.size(); ++i)
    for (int bit = 0; bit < 8; ++bit) {
      std::vector<std::uint8_t> b = good;
      b[i] ^= static_cast<std::uint8_t>(1u << bit);
      ASSERT_NE(parse_tactile(b), ParseResult::Ok) << "byte " << i << " bit " << bit;
    }
  std::vector<std::uint8_t> v2 = good;
  v2[4] = 2;
  reseal(v2);
  EXPECT_EQ(parse_tactile(v2), ParseResult::BadVersion);
  EXPECT_EQ(parse_tactile(good, 3), ParseResult::Malformed);
  udp::TactilePacket nan = sample_tactile();
  nan.frames.finger[1].pins[5] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(parse_tactile(encode_tactile(nan)), ParseResult::OutOfRange);
  std::vector<std::uint8_t> many = good;
  many[7] = 17;  // samples past a frame's 16
  reseal(many);
  EXPECT_EQ(parse_tactile(many), ParseResult::Malformed);
  udp::TactilePacket bad = sample_tactile();
  bad.rows = 9;
  bad.cols = 9;
  EXPECT_EQ(encode_tactile(bad).size(), 0u);
  bad = sample_tactile();
  bad.samples = 17;
  EXPECT_EQ(encode_tactile(bad).size(), 0u);
  std::uint8_t small[100];
  EXPECT_EQ(udp::encode_tactile_packet(sample_tactile(), small, sizeof small), 0u);
}
