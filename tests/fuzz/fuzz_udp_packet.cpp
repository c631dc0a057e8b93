// Fuzz target for the UDP packet decoders (devices/udp/wire.hpp): any bytes must decode without
// a crash or undefined behaviour, and a packet accepted as Ok must honour the protocol's
// promises (right size and finger count, finite values, positions inside the workspace,
// re-encoding gives the same bytes). A broken promise aborts.

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "udp/wire.hpp"

namespace udp = hapticloth::devices::udp;
using hapticloth::devices::Box;
using hapticloth::devices::kMaxFingers;

/// Decoder outcomes so far (read by the standalone driver).
std::uint64_t g_fuzz_state_ok = 0, g_fuzz_force_ok = 0, g_fuzz_tactile_ok = 0, g_fuzz_rejected = 0;

namespace {

[[noreturn]] void broken(const char* what) {
  std::fprintf(stderr, "fuzz_udp_packet: invariant broken: %s\n", what);
  std::abort();
}

void check(bool ok, const char* what) {
  if (!ok) broken(what);
}

void count(udp::ParseResult r, std::uint64_t& ok) {
  if (r == udp::ParseResult::Ok)
    ++ok;
  else
    ++g_fuzz_rejected;
  check(r == udp::ParseResult::Ok || r == udp::ParseResult::Malformed ||
            r == udp::ParseResult::BadVersion || r == udp::ParseResult::OutOfRange,
        "result is a ParseResult");
}

bool finite(const hapticloth::devices::Vec3& v) { return v.allFinite(); }

// A decoder's result on the bytes, counted in `ok` or as rejected: true if Ok, and then a finger
// count in range and, when one is expected, the expected one; else the output untouched.
template <class Packet>
bool accepted(udp::ParseResult r, const Packet& p, int expected, std::uint64_t& ok) {
  count(r, ok);
  if (r != udp::ParseResult::Ok) {
    check(p.fingers == -7, "output untouched on failure");
    return false;
  }
  check(p.fingers >= 1 && p.fingers <= kMaxFingers, "finger count in range");
  check(expected <= 0 || p.fingers == expected, "finger count as expected");
  return true;
}

void state_target(const std::uint8_t* data, std::size_t size, int expected, const Box& ws) {
  udp::StatePacket p;
  p.fingers = -7;  // must stay untouched unless Ok
  if (!accepted(udp::parse_state_packet(data, size, expected, ws, p), p, expected, g_fuzz_state_ok)) return;
  check(p.fingers == expected, "finger count");
  check(size == udp::state_packet_size(p.fingers), "size");
  check(std::isfinite(p.device_time), "finite device_time");
  for (int i = 0; i < p.fingers; ++i) {
    check(finite(p.finger[i].position) && finite(p.finger[i].velocity), "finite finger state");
    check(ws.contains(p.finger[i].position), "position inside the workspace");
  }
  std::uint8_t again[udp::kMaxStatePacketBytes];
  check(udp::encode_state_packet(p, again, sizeof again) == size, "re-encoded size");
  if (data[7] == 0) check(std::memcmp(again, data, size) == 0, "re-encoded bytes");
}

void force_target(const std::uint8_t* data, std::size_t size, int expected) {
  udp::ForcePacket p;
  p.fingers = -7;
  if (!accepted(udp::parse_force_packet(data, size, expected, p), p, expected, g_fuzz_force_ok)) return;
  check(size == udp::force_packet_size(p.fingers), "size");
  check(std::isfinite(p.server_time), "finite server_time");
  for (int i = 0; i < p.fingers; ++i) check(finite(p.force[i]), "finite force");
  std::uint8_t again[udp::kMaxForcePacketBytes];
  check(udp::encode_force_packet(p, again, sizeof again) == size, "re-encoded size");
  if (data[7] == 0 && data[28] == 0 && data[29] == 0 && data[30] == 0 && data[31] == 0)
    check(std::memcmp(again, data, size) == 0, "re-encoded bytes");
}

void tactile_target(const std::uint8_t* data, std::size_t size, int expected) {
  udp::TactilePacket p;
  p.fingers = -7;
  if (!accepted(udp::parse_tactile_packet(data, size, expected, p), p, expected, g_fuzz_tactile_ok)) return;
  check(p.samples >= 0 && p.samples <= hapticloth::devices::kMaxTactileSamples, "samples in range");
  check(p.rows * p.cols <= hapticloth::devices::kMaxPins, "pins in range");
  check(size == udp::tactile_packet_size(p.fingers, p.samples, p.rows * p.cols), "tactile size");
  check(std::isfinite(p.server_time), "finite server_time");
  for (int f = 0; f < p.fingers; ++f) {
    const auto& fr = p.frames.finger[f];
    for (int k = 0; k < p.samples; ++k) check(std::isfinite(fr.vibration[k]), "finite sample");
    for (int k = 0; k < p.rows * p.cols; ++k) check(std::isfinite(fr.pins[k]), "finite pin");
  }
  std::uint8_t again[udp::kMaxTactilePacketBytes];
  check(udp::encode_tactile_packet(p, again, sizeof again) == size, "tactile re-encoded size");
  check(std::memcmp(again, data, size) == 0, "tactile re-encoded bytes");  // no reserved field
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const Box kDefault{};  // +-0.1 m
  static const Box kFlat{hapticloth::devices::Vec3(-0.2, -0.2, 0.0),
                         hapticloth::devices::Vec3(0.2, 0.2, 0.0)};  // a zero-thickness box
  // The finger count the packet claims, the default two, and impossible ones.
  const int claimed = size > 6 ? data[6] : 2;
  for (int expected : {2, claimed, 0}) {
    state_target(data, size, expected, kDefault);
    force_target(data, size, expected);
    tactile_target(data, size, expected);
  }
  state_target(data, size, claimed, kFlat);
  return 0;
}
