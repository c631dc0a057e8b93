// Packets and options shared by the UDP device's tests (tests/devices/test_udp_*.cpp).
#pragma once

#include <cstdint>
#include <vector>

#include "hal/options.hpp"
#include "udp/wire.hpp"

namespace hapticloth::test {

using devices::Vec3;
using devices::DeviceOptions;

inline devices::udp::StatePacket sample_state(int fingers) {
  devices::udp::StatePacket p;
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

inline std::vector<std::uint8_t> encode(const devices::udp::StatePacket& p) {
  std::vector<std::uint8_t> b(devices::udp::kMaxStatePacketBytes);
  b.resize(devices::udp::encode_state_packet(p, b.data(), b.size()));
  return b;
}

inline std::vector<std::uint8_t> encode(const devices::udp::ForcePacket& p) {
  std::vector<std::uint8_t> b(devices::udp::kMaxForcePacketBytes);
  b.resize(devices::udp::encode_force_packet(p, b.data(), b.size()));
  return b;
}

/// A UDP device bound to a free port on 127.0.0.1.
inline DeviceOptions loopback_options() {
  DeviceOptions opt;
  opt.driver = "udp";
  opt.udp_bind = "127.0.0.1:0";
  return opt;
}

inline void reseal(std::vector<std::uint8_t>& b) {  // recompute the CRC after an edit
  const std::uint32_t c = devices::udp::crc32(b.data(), b.size() - 4);
  for (int i = 0; i < 4; ++i) b[b.size() - 4 + i] = static_cast<std::uint8_t>(c >> (8 * i));
}

}  // namespace hapticloth::test
