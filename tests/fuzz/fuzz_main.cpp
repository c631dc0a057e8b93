// Standalone driver for fuzz_udp_packet when libFuzzer is not available (g++): runs the target
// on seeded random inputs and mutations of valid packets, then prints a JSON line.
//
//   fuzz_udp_packet --runs 1000000 --seed 1
//
// Inputs, in equal shares: random bytes; valid state, force or tactile packets (1..5 fingers, random
// values in and around the workspace) under 1-8 mutations (bit flips, random or boundary
// bytes, special doubles written into a field, insertions, deletions, truncations, extensions,
// splices with another packet); half of the mutated packets get a correct CRC again so that the
// checks behind the CRC are reached. A broken invariant or a sanitizer finding aborts.

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "udp/wire.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size);
extern std::uint64_t g_fuzz_state_ok, g_fuzz_force_ok, g_fuzz_tactile_ok, g_fuzz_rejected;

namespace {

namespace udp = hapticloth::devices::udp;
using hapticloth::devices::Vec3;
using Bytes = std::vector<std::uint8_t>;
using Rng = std::mt19937_64;

double coordinate(Rng& rng) {
  // Mostly inside the +-0.1 m default workspace, sometimes just outside or on its boundary.
  switch (rng() % 8) {
    case 0: return (rng() % 2 ? 0.1 : -0.1);
    case 1: return std::uniform_real_distribution<double>(-0.2, 0.2)(rng);
    default: return std::uniform_real_distribution<double>(-0.1, 0.1)(rng);
  }
}

Bytes valid_packet(Rng& rng) {
  const int fingers = 1 + static_cast<int>(rng() % 5);
  Bytes b(udp::kMaxTactilePacketBytes);
  const unsigned kind = rng() % 3;
  if (kind == 2) {
    udp::TactilePacket p;
    p.sequence = rng();
    p.server_time = std::uniform_real_distribution<double>(0, 1e4)(rng);
    p.flags = static_cast<std::uint32_t>(rng() % 8);
    p.sample_rate = 1000 * static_cast<int>(1 + rng() % 16);
    p.fingers = fingers;
    p.samples = static_cast<int>(rng() % 17);
    p.rows = static_cast<int>(rng() % 9);
    p.cols = p.rows ? static_cast<int>(rng() % (64 / p.rows + 1)) : 0;
    for (int f = 0; f < fingers; ++f) {
      auto& fr = p.frames.finger[f];
      fr.samples = p.samples;
      fr.rows = p.rows;
      fr.cols = p.cols;
      for (int k = 0; k < p.samples; ++k) fr.vibration[k] = static_cast<float>(coordinate(rng) * 1e-3);
      for (int k = 0; k < p.rows * p.cols; ++k) fr.pins[k] = static_cast<float>(coordinate(rng) * 1e-2);
    }
    b.resize(udp::encode_tactile_packet(p, b.data(), b.size()));
  } else if (kind == 1) {
    udp::StatePacket p;
    p.sequence = rng();
    p.device_time = std::uniform_real_distribution<double>(0, 1e4)(rng);
    p.fingers = fingers;
    for (int i = 0; i < fingers; ++i) {
      p.finger[i].position = Vec3(coordinate(rng), coordinate(rng), coordinate(rng));
      p.finger[i].velocity = Vec3(coordinate(rng), coordinate(rng), coordinate(rng)) * 10.0;
      p.finger[i].buttons = static_cast<std::uint32_t>(rng());
    }
    b.resize(udp::encode_state_packet(p, b.data(), b.size()));
  } else {
    udp::ForcePacket p;
    p.sequence = rng();
    p.server_time = std::uniform_real_distribution<double>(0, 1e4)(rng);
    p.flags = static_cast<std::uint32_t>(rng() % 8);
    p.fingers = fingers;
    for (int i = 0; i < fingers; ++i)
      p.force[i] = Vec3(coordinate(rng), coordinate(rng), coordinate(rng)) * 50.0;
    b.resize(udp::encode_force_packet(p, b.data(), b.size()));
  }
  return b;
}

void special_double(Rng& rng, Bytes& b) {
  static const double kSpecial[] = {std::numeric_limits<double>::quiet_NaN(),
                                    std::numeric_limits<double>::signaling_NaN(),
                                    std::numeric_limits<double>::infinity(),
                                    -std::numeric_limits<double>::infinity(),
                                    std::numeric_limits<double>::denorm_min(),
                                    std::numeric_limits<double>::max(),
                                    -0.0, 0.1, -0.1, 0.1000000000000001, 1e300};
  if (b.size() < 8) return;
  const double v = kSpecial[rng() % (sizeof kSpecial / sizeof kSpecial[0])];
  // Aligned with the packets' 8-byte fields most of the time.
  std::size_t at = rng() % 4 ? 8 * (rng() % (b.size() / 8)) : rng() % (b.size() - 7);
  std::memcpy(b.data() + at, &v, 8);
}

void mutate(Rng& rng, Bytes& b, const Bytes& other) {
  static const std::uint8_t kBoundary[] = {0, 1, 2, 5, 6, 0x7F, 0x80, 0xFF};
  switch (rng() % 10) {
    case 0:
      if (!b.empty()) b[rng() % b.size()] ^= static_cast<std::uint8_t>(1u << (rng() % 8));
      break;
    case 1:
      if (!b.empty()) b[rng() % b.size()] = static_cast<std::uint8_t>(rng());
      break;
    case 2:
      if (!b.empty()) b[rng() % b.size()] = kBoundary[rng() % sizeof kBoundary];
      break;
    case 3: special_double(rng, b); break;
    case 4: b.insert(b.begin() + static_cast<long>(rng() % (b.size() + 1)),
                     static_cast<std::uint8_t>(rng()));
      break;
    case 5:
      if (!b.empty()) b.erase(b.begin() + static_cast<long>(rng() % b.size()));
      break;
    case 6: b.resize(rng() % (b.size() + 1)); break;
    case 7: b.resize(b.size() + 1 + rng() % 64, static_cast<std::uint8_t>(rng())); break;
    case 8: {  // splice: a prefix of this packet, the rest from another
      const std::size_t cut = rng() % (b.size() + 1);
      const std::size_t from = other.empty() ? 0 : rng() % other.size();
      b.resize(cut);
      b.insert(b.end(), other.begin() + static_cast<long>(from), other.end());
      break;
    }
    case 9:  // the finger count byte
      if (b.size() > 6) b[6] = static_cast<std::uint8_t>(rng() % 8);
      break;
  }
}

void reseal(Bytes& b) {
  if (b.size() < 4) return;
  const std::uint32_t c = udp::crc32(b.data(), b.size() - 4);
  for (int i = 0; i < 4; ++i) b[b.size() - 4 + i] = static_cast<std::uint8_t>(c >> (8 * i));
}

int usage(const char* argv0) {
  std::fprintf(stderr, "usage: %s [--runs N] [--seed S]\n", argv0);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::uint64_t runs = 100000, seed = 1;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if ((a == "--runs" || a == "--seed") && i + 1 < argc) {
      char* end = nullptr;
      const unsigned long long v = std::strtoull(argv[++i], &end, 10);
      if (*end != '\0') return usage(argv[0]);
      (a == "--runs" ? runs : seed) = v;
    } else {
      return usage(argv[0]);
    }
  }
  Rng rng(seed);
  Bytes input, other;
  input.reserve(4096);
  for (std::uint64_t run = 0; run < runs; ++run) {
    const unsigned kind = rng() % 4;
    if (kind == 0) {
      input.resize(rng() % 600);
      for (auto& c : input) c = static_cast<std::uint8_t>(rng());
      if (rng() % 2 && input.size() >= 4) std::memcpy(input.data(), rng() % 3 == 0 ? "HCST" : rng() % 2 ? "HCFC" : "HCTA", 4);
    } else {
      input = valid_packet(rng);
      if (kind != 3) {
        other = valid_packet(rng);
        const int n = 1 + static_cast<int>(rng() % 8);
        for (int m = 0; m < n; ++m) mutate(rng, input, other);
        if (rng() % 2) reseal(input);
      }
    }
    LLVMFuzzerTestOneInput(input.data(), input.size());
  }
  std::printf(
      "{\"runs\": %llu, \"crashes\": 0, \"seed\": %llu, \"state_ok\": %llu, \"force_ok\": %llu, "
      "\"tactile_ok\": %llu, \"rejected\": %llu}\n",
      static_cast<unsigned long long>(runs), static_cast<unsigned long long>(seed),
      static_cast<unsigned long long>(g_fuzz_state_ok),
      static_cast<unsigned long long>(g_fuzz_force_ok),
      static_cast<unsigned long long>(g_fuzz_tactile_ok),
      static_cast<unsigned long long>(g_fuzz_rejected));
  return 0;
}
