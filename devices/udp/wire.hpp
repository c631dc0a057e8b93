// The UDP device wire format, version 1 (proto/udp_device.md): pure encoders and decoders.
// No I/O, no allocation, no exceptions: safe on the real-time path and for any input bytes.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "hal/device.hpp"

namespace hapticloth::devices::udp {

inline constexpr std::uint16_t kProtocolVersion = 1;
inline constexpr std::array<std::uint8_t, 4> kStateMagic{'H', 'C', 'S', 'T'};
inline constexpr std::array<std::uint8_t, 4> kForceMagic{'H', 'C', 'F', 'C'};
inline constexpr std::array<std::uint8_t, 4> kTactileMagic{'H', 'C', 'T', 'A'};
/// The tactile message's own version (proto/udp_device.md, "Tactile packet"): a rig that knows
/// only force packets ignores it by its magic.
inline constexpr std::uint16_t kTactileVersion = 1;

inline constexpr std::size_t kStateHeaderBytes = 24;  ///< magic .. device_time
inline constexpr std::size_t kStateFingerBytes = 52;  ///< position, velocity, buttons
inline constexpr std::size_t kForceHeaderBytes = 32;  ///< magic .. reserved
inline constexpr std::size_t kForceFingerBytes = 24;  ///< force
inline constexpr std::size_t kTactileHeaderBytes = 32;  ///< magic .. pin columns
inline constexpr std::size_t kCrcBytes = 4;

/// CRC-32 of zlib / IEEE 802.3 (reflected polynomial 0xEDB88320, init and final XOR ~0).
std::uint32_t crc32(const std::uint8_t* p, std::size_t n) noexcept;

/// Bytes of a state / force packet with `fingers` fingers (fingers in 1..kMaxFingers).
constexpr std::size_t state_packet_size(int fingers) {
  return kStateHeaderBytes + kStateFingerBytes * static_cast<std::size_t>(fingers) + kCrcBytes;
}
constexpr std::size_t force_packet_size(int fingers) {
  return kForceHeaderBytes + kForceFingerBytes * static_cast<std::size_t>(fingers) + kCrcBytes;
}
/// Bytes of a tactile packet: per finger `samples` vibration samples and rows x cols pins, f32.
constexpr std::size_t tactile_packet_size(int fingers, int samples, int pins) {
  return kTactileHeaderBytes + 4 * static_cast<std::size_t>(fingers) * static_cast<std::size_t>(samples + pins) + kCrcBytes;
}
inline constexpr std::size_t kMaxTactilePacketBytes = tactile_packet_size(kMaxFingers, kMaxTactileSamples, kMaxPins);
inline constexpr std::size_t kMaxStatePacketBytes = state_packet_size(kMaxFingers);
inline constexpr std::size_t kMaxForcePacketBytes = force_packet_size(kMaxFingers);

/// What a decoder made of a datagram; each non-Ok result maps to one DeviceCounters field.
enum class ParseResult : std::uint8_t {
  Ok,
  Malformed,   ///< size, magic, CRC or finger count wrong  -> dropped_malformed
  BadVersion,  ///< version != 1                             -> dropped_version
  OutOfRange,  ///< non-finite number or position outside the workspace -> dropped_out_of_range
};
const char* to_string(ParseResult r);

/// A state packet (rig -> server), decoded.
struct StatePacket {
  std::uint64_t sequence = 0;
  double device_time = 0.0;  ///< s, the rig's clock
  int fingers = 0;
  std::array<FingerState, kMaxFingers> finger{};  ///< [0, fingers) are meaningful
};

/// A force packet (server -> rig), decoded.
struct ForcePacket {
  std::uint64_t sequence = 0;  ///< newest state sequence the server had taken
  double server_time = 0.0;    ///< s, the server's loop clock
  std::uint32_t flags = 0;     ///< CommandFlags
  int fingers = 0;
  std::array<Vec3, kMaxFingers> force{};  ///< N, [0, fingers) are meaningful
};

/// A tactile packet (server -> rig), decoded: one tick's vibration block and pin frame per
/// finger, every finger with the same block length and pin layout.
struct TactilePacket {
  std::uint64_t sequence = 0;  ///< as the force packet of the same tick
  double server_time = 0.0;    ///< s
  std::uint32_t flags = 0;     ///< TactileFlags (hal/tactile.hpp)
  int sample_rate = 0;         ///< Hz of the vibration samples
  int fingers = 0, samples = 0, rows = 0, cols = 0;
  TactileCommand frames;       ///< [0, fingers): samples and pins as above, m
};

/// Decodes a state packet. Checks, in this order: at least 8 bytes and the magic (Malformed),
/// the version (BadVersion), the finger count equals `expected_fingers` (Malformed), the exact
/// size and the CRC (Malformed), then every number finite and every position inside
/// `workspace` (OutOfRange). The reserved byte is ignored. `out` is written only on Ok.
ParseResult parse_state_packet(const std::uint8_t* data, std::size_t len, int expected_fingers,
                               const Box& workspace, StatePacket& out) noexcept;

/// Decodes a force packet, with the same checks and order as parse_state_packet (no workspace;
/// OutOfRange means a non-finite force or time). `expected_fingers` <= 0 accepts 1..kMaxFingers.
ParseResult parse_force_packet(const std::uint8_t* data, std::size_t len, int expected_fingers,
                               ForcePacket& out) noexcept;

/// Decodes a tactile packet: at least 8 bytes and the magic (Malformed), the tactile version
/// (BadVersion), fingers in 1..kMaxFingers and equal to `expected_fingers` if that is > 0,
/// samples <= kMaxTactileSamples, rows x cols <= kMaxPins (Malformed), the exact size and the
/// CRC (Malformed), then every number finite (OutOfRange). `out` is written only on Ok.
ParseResult parse_tactile_packet(const std::uint8_t* data, std::size_t len, int expected_fingers,
                                 TactilePacket& out) noexcept;

/// Encodes into `buf`; returns the bytes written, or 0 if p.fingers is not in 1..kMaxFingers or
/// `cap` is too small. Values are written as given (non-finite ones too: tests need them).
std::size_t encode_state_packet(const StatePacket& p, std::uint8_t* buf, std::size_t cap) noexcept;
std::size_t encode_force_packet(const ForcePacket& p, std::uint8_t* buf, std::size_t cap) noexcept;
/// 0 also if samples, rows or cols are out of range.
std::size_t encode_tactile_packet(const TactilePacket& p, std::uint8_t* buf, std::size_t cap) noexcept;

}  // namespace hapticloth::devices::udp
