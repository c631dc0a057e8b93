#include "udp/wire.hpp"

#include <bit>
#include <cmath>

namespace hapticloth::devices::udp {

namespace {

constexpr std::array<std::uint32_t, 256> make_crc_table() {
  std::array<std::uint32_t, 256> table{};
  for (std::uint32_t i = 0; i < 256; ++i) {
    std::uint32_t c = i;
    for (int k = 0; k < 8; ++k) c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
    table[i] = c;
  }
  return table;
}
constexpr std::array<std::uint32_t, 256> kCrcTable = make_crc_table();

// Little-endian field access, independent of the host's byte order and alignment.
std::uint16_t load_u16(const std::uint8_t* p) {
  return static_cast<std::uint16_t>(p[0] | (p[1] << 8));
}
std::uint32_t load_u32(const std::uint8_t* p) {
  return std::uint32_t{p[0]} | (std::uint32_t{p[1]} << 8) | (std::uint32_t{p[2]} << 16) |
         (std::uint32_t{p[3]} << 24);
}
std::uint64_t load_u64(const std::uint8_t* p) {
  return std::uint64_t{load_u32(p)} | (std::uint64_t{load_u32(p + 4)} << 32);
}
double load_f64(const std::uint8_t* p) { return std::bit_cast<double>(load_u64(p)); }
float load_f32(const std::uint8_t* p) { return std::bit_cast<float>(load_u32(p)); }
Vec3 load_vec3(const std::uint8_t* p) { return {load_f64(p), load_f64(p + 8), load_f64(p + 16)}; }

void store_u16(std::uint8_t* p, std::uint16_t v) {
  p[0] = static_cast<std::uint8_t>(v);
  p[1] = static_cast<std::uint8_t>(v >> 8);
}
void store_u32(std::uint8_t* p, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}
void store_u64(std::uint8_t* p, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}
void store_f64(std::uint8_t* p, double v) { store_u64(p, std::bit_cast<std::uint64_t>(v)); }
void store_f32(std::uint8_t* p, float v) { store_u32(p, std::bit_cast<std::uint32_t>(v)); }
void store_vec3(std::uint8_t* p, const Vec3& v) {
  for (int k = 0; k < 3; ++k) store_f64(p + 8 * k, v[k]);
}

bool finite(const Vec3& v) {
  return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]);
}

/// The checks shared by both packet kinds, up to and including the CRC. On Ok, `fingers` is the
/// packet's finger count and `len` its exact size.
ParseResult check_frame(const std::uint8_t* data, std::size_t len,
                        const std::array<std::uint8_t, 4>& magic, int expected_fingers,
                        std::size_t (*size_of)(int), int& fingers) {
  if (data == nullptr || len < 8) return ParseResult::Malformed;
  for (int i = 0; i < 4; ++i)
    if (data[i] != magic[i]) return ParseResult::Malformed;
  if (load_u16(data + 4) != kProtocolVersion) return ParseResult::BadVersion;
  fingers = data[6];
  if (fingers < 1 || fingers > kMaxFingers) return ParseResult::Malformed;
  if (expected_fingers > 0 && fingers != expected_fingers) return ParseResult::Malformed;
  const std::size_t size = size_of(fingers);
  if (len != size) return ParseResult::Malformed;
  if (load_u32(data + size - kCrcBytes) != crc32(data, size - kCrcBytes))
    return ParseResult::Malformed;
  return ParseResult::Ok;
}

std::size_t state_size_of(int fingers) { return state_packet_size(fingers); }
std::size_t force_size_of(int fingers) { return force_packet_size(fingers); }

void store_header(std::uint8_t* buf, const std::array<std::uint8_t, 4>& magic, int fingers,
                  std::uint64_t sequence, double time) {
  for (int i = 0; i < 4; ++i) buf[i] = magic[i];
  store_u16(buf + 4, kProtocolVersion);
  buf[6] = static_cast<std::uint8_t>(fingers);
  buf[7] = 0;
  store_u64(buf + 8, sequence);
  store_f64(buf + 16, time);
}

}  // namespace

const char* to_string(ParseResult r) {
  switch (r) {
    case ParseResult::Ok: return "ok";
    case ParseResult::Malformed: return "malformed";
    case ParseResult::BadVersion: return "bad version";
    case ParseResult::OutOfRange: return "out of range";
  }
  return "?";
}

std::uint32_t crc32(const std::uint8_t* p, std::size_t n) noexcept {
  std::uint32_t c = 0xFFFFFFFFu;
  for (std::size_t i = 0; i < n; ++i) c = kCrcTable[(c ^ p[i]) & 0xFFu] ^ (c >> 8);
  return c ^ 0xFFFFFFFFu;
}

ParseResult parse_state_packet(const std::uint8_t* data, std::size_t len, int expected_fingers,
                               const Box& workspace, StatePacket& out) noexcept {
  int fingers = 0;
  const ParseResult frame =
      check_frame(data, len, kStateMagic, expected_fingers, state_size_of, fingers);
  if (frame != ParseResult::Ok) return frame;
  if (expected_fingers < 1) return ParseResult::Malformed;  // a server expects a finger count

  StatePacket p;
  p.sequence = load_u64(data + 8);
  p.device_time = load_f64(data + 16);
  p.fingers = fingers;
  if (!std::isfinite(p.device_time)) return ParseResult::OutOfRange;
  for (int i = 0; i < fingers; ++i) {
    const std::uint8_t* f = data + kStateHeaderBytes + kStateFingerBytes * i;
    FingerState& s = p.finger[i];
    s.position = load_vec3(f);
    s.velocity = load_vec3(f + 24);
    s.buttons = load_u32(f + 48);
    if (!finite(s.position) || !finite(s.velocity) || !workspace.contains(s.position))
      return ParseResult::OutOfRange;
  }
  out = p;
  return ParseResult::Ok;
}

ParseResult parse_force_packet(const std::uint8_t* data, std::size_t len, int expected_fingers,
                               ForcePacket& out) noexcept {
  int fingers = 0;
  const ParseResult frame =
      check_frame(data, len, kForceMagic, expected_fingers, force_size_of, fingers);
  if (frame != ParseResult::Ok) return frame;

  ForcePacket p;
  p.sequence = load_u64(data + 8);
  p.server_time = load_f64(data + 16);
  p.flags = load_u32(data + 24);
  p.fingers = fingers;
  if (!std::isfinite(p.server_time)) return ParseResult::OutOfRange;
  for (int i = 0; i < fingers; ++i) {
    p.force[i] = load_vec3(data + kForceHeaderBytes + kForceFingerBytes * i);
    if (!finite(p.force[i])) return ParseResult::OutOfRange;
  }
  out = p;
  return ParseResult::Ok;
}

ParseResult parse_tactile_packet(const std::uint8_t* data, std::size_t len, int expected_fingers,
                                 TactilePacket& out) noexcept {
  if (data == nullptr || len < 8) return ParseResult::Malformed;
  for (int i = 0; i < 4; ++i)
    if (data[i] != kTactileMagic[i]) return ParseResult::Malformed;
  if (load_u16(data + 4) != kTactileVersion) return ParseResult::BadVersion;
  if (len < kTactileHeaderBytes + kCrcBytes) return ParseResult::Malformed;
  const int fingers = data[6], samples = data[7], rows = data[30], cols = data[31];
  if (fingers < 1 || fingers > kMaxFingers || (expected_fingers > 0 && fingers != expected_fingers) ||
      samples > kMaxTactileSamples || rows * cols > kMaxPins)
    return ParseResult::Malformed;
  const std::size_t size = tactile_packet_size(fingers, samples, rows * cols);
  if (len != size || load_u32(data + size - kCrcBytes) != crc32(data, size - kCrcBytes)) return ParseResult::Malformed;
  TactilePacket p;
  p.sequence = load_u64(data + 8);
  p.server_time = load_f64(data + 16);
  p.flags = load_u32(data + 24);
  p.sample_rate = load_u16(data + 28);
  p.fingers = fingers;
  p.samples = samples;
  p.rows = rows;
  p.cols = cols;
  if (!std::isfinite(p.server_time)) return ParseResult::OutOfRange;
  const std::uint8_t* at = data + kTactileHeaderBytes;
  for (int f = 0; f < fingers; ++f) {
    TactileFrame& fr = p.frames.finger[f];
    fr.samples = samples;
    fr.rows = rows;
    fr.cols = cols;
    for (int k = 0; k < samples; ++k, at += 4) fr.vibration[k] = load_f32(at);
    for (int k = 0; k < rows * cols; ++k, at += 4) fr.pins[k] = load_f32(at);
    for (int k = 0; k < samples; ++k)
      if (!std::isfinite(fr.vibration[k])) return ParseResult::OutOfRange;
    for (int k = 0; k < rows * cols; ++k)
      if (!std::isfinite(fr.pins[k])) return ParseResult::OutOfRange;
  }
  p.frames.flags = p.flags;
  out = p;
  return ParseResult::Ok;
}

// The size of a packet of `fingers` fingers if it fits in `cap` bytes of `buf`, else 0.
static std::size_t room_for(int fingers, const std::uint8_t* buf, std::size_t cap,
                            std::size_t (*size_of)(int)) noexcept {
  if (fingers < 1 || fingers > kMaxFingers || buf == nullptr) return 0;
  const std::size_t size = size_of(fingers);
  return cap < size ? 0 : size;
}

std::size_t encode_state_packet(const StatePacket& p, std::uint8_t* buf,
                                std::size_t cap) noexcept {
  const std::size_t size = room_for(p.fingers, buf, cap, state_packet_size);
  if (size == 0) return 0;
  store_header(buf, kStateMagic, p.fingers, p.sequence, p.device_time);
  for (int i = 0; i < p.fingers; ++i) {
    std::uint8_t* f = buf + kStateHeaderBytes + kStateFingerBytes * i;
    store_vec3(f, p.finger[i].position);
    store_vec3(f + 24, p.finger[i].velocity);
    store_u32(f + 48, p.finger[i].buttons);
  }
  store_u32(buf + size - kCrcBytes, crc32(buf, size - kCrcBytes));
  return size;
}

std::size_t encode_force_packet(const ForcePacket& p, std::uint8_t* buf,
                                std::size_t cap) noexcept {
  const std::size_t size = room_for(p.fingers, buf, cap, force_packet_size);
  if (size == 0) return 0;
  store_header(buf, kForceMagic, p.fingers, p.sequence, p.server_time);
  store_u32(buf + 24, p.flags);
  store_u32(buf + 28, 0);
  for (int i = 0; i < p.fingers; ++i)
    store_vec3(buf + kForceHeaderBytes + kForceFingerBytes * i, p.force[i]);
  store_u32(buf + size - kCrcBytes, crc32(buf, size - kCrcBytes));
  return size;
}

std::size_t encode_tactile_packet(const TactilePacket& p, std::uint8_t* buf, std::size_t cap) noexcept {
  if (p.fingers < 1 || p.fingers > kMaxFingers || buf == nullptr || p.samples < 0 || p.samples > kMaxTactileSamples ||
      p.rows < 0 || p.cols < 0 || p.rows > 255 || p.cols > 255 || p.rows * p.cols > kMaxPins || p.sample_rate < 0 ||
      p.sample_rate > 0xFFFF)
    return 0;
  const std::size_t size = tactile_packet_size(p.fingers, p.samples, p.rows * p.cols);
  if (cap < size) return 0;
  store_header(buf, kTactileMagic, p.fingers, p.sequence, p.server_time);
  store_u16(buf + 4, kTactileVersion);
  buf[7] = static_cast<std::uint8_t>(p.samples);
  store_u32(buf + 24, p.flags);
  store_u16(buf + 28, static_cast<std::uint16_t>(p.sample_rate));
  buf[30] = static_cast<std::uint8_t>(p.rows);
  buf[31] = static_cast<std::uint8_t>(p.cols);
  std::uint8_t* at = buf + kTactileHeaderBytes;
  for (int f = 0; f < p.fingers; ++f) {
    const TactileFrame& fr = p.frames.finger[f];
    for (int k = 0; k < p.samples; ++k, at += 4) store_f32(at, k < fr.samples ? fr.vibration[k] : 0.0f);
    const bool pins = fr.rows == p.rows && fr.cols == p.cols;
    for (int k = 0; k < p.rows * p.cols; ++k, at += 4) store_f32(at, pins ? fr.pins[k] : 0.0f);
  }
  store_u32(buf + size - kCrcBytes, crc32(buf, size - kCrcBytes));
  return size;
}

}  // namespace hapticloth::devices::udp
