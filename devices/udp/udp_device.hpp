// The UDP device: a haptic rig streams state packets to a bound UDP socket and receives one
// force packet per loop tick (protocol: proto/udp_device.md).
//
// read() drains every pending datagram (at most kMaxDatagramsPerRead per call), keeps the
// newest valid sample and counts each dropped datagram under the counter the protocol names.
// write() answers the sender of the newest valid sample. Both are non-blocking, allocation-free
// and never throw.
//
// A session is one rig's: activate() discards what was queued before it (a rig that streams
// while the cloth settles), the first valid sample's sender is the session's rig, and another
// sender's packets are counted and dropped. When the newest sample a read finds is older, by the
// rig's clock, than the watchdog, it is stale and dropped: its age is its offset (loop clock at
// reading - device_time)
// above the smallest offset seen, the sample that waited least, which may creep up at
// kClockDrift to follow a rig clock that runs slow (proto/udp_device.md).
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>

#include <netinet/in.h>

#include "hal/device.hpp"
#include "hal/options.hpp"
#include "log/device_log.hpp"
#include "udp/wire.hpp"

namespace hapticloth::devices {

/// An IPv4 endpoint parsed from "HOST:PORT".
struct UdpEndpoint {
  std::uint32_t address = 0;  ///< host byte order
  std::uint16_t port = 0;     ///< 0: any free port (see UdpDevice::local_port)
};

/// Parses "HOST:PORT" where HOST is a numeric IPv4 address or "localhost" and PORT is 0..65535.
/// Returns an empty string on success, else what is wrong (naming `udp_bind`).
std::string parse_udp_endpoint(const std::string& text, UdpEndpoint& out);

class UdpDevice final : public DeviceDriver {
 public:
  /// Datagrams read per read() call at most (bounds the time read() takes under a flood).
  static constexpr int kMaxDatagramsPerRead = 256;
  /// Datagrams activate() discards at most (far more than a full receive buffer holds).
  static constexpr int kMaxBacklog = 1 << 20;
  /// s/s: how fast the rig's clock may fall behind the loop's (1000 ppm; quartz drifts < 100).
  static constexpr double kClockDrift = 1e-3;
  /// s: a rig sending only stale samples this long has had its clock jump back: resynchronized.
  static constexpr double kClockResync = 1.0;

  /// Throws std::invalid_argument naming the field for a bad udp_bind or finger count.
  explicit UdpDevice(const DeviceOptions& opt);
  ~UdpDevice() override;
  UdpDevice(const UdpDevice&) = delete;
  UdpDevice& operator=(const UdpDevice&) = delete;

  // The Device interface (hal/device.hpp).
  /// Creates, binds and makes non-blocking the socket. Returns the error (for example the port
  /// is in use); never throws.
  std::string configure() override;
  /// Reopens the socket if a deactivate closed it; reserves the device log.
  std::string activate() override;
  /// Sends one zero-force packet to the known peer, closes the socket, writes the device log
  /// (throws std::runtime_error if the log cannot be written; the socket is closed first).
  void deactivate() override;

  /// Real-time path. Ok: a new valid sample was taken (state filled); NoData: none arrived;
  /// Error: the socket is not open or failed.
  Status read(double now, DeviceState& state) noexcept override;
  /// Real-time path. Ok: sent; NoData: no rig has sent a valid sample yet, or a transient send
  /// failure (counted in send_errors); Error: the socket is not open or broken. Non-finite
  /// forces are sent as zero with kFlagFault set.
  Status write(double now, const DeviceCommand& cmd) noexcept override;
  /// Real-time path, with a tactile display declared ([device.tactile]): the tick's tactile
  /// packet to the same peer as the force packets (proto/udp_device.md). Statuses as write().
  Status write_tactile(double now, const TactileCommand& cmd) noexcept override;
  /// The rig streams on its own clock: it can pace the loop (DeviceClock).
  bool paces_loop() const override { return true; }
  /// Real-time path: ppoll on the socket until a datagram is ready (true) or `until` passes.
  bool await_sample(double until) noexcept override;

  /// The bound UDP port (after configure; useful with port 0).
  std::uint16_t local_port() const { return local_port_; }
  /// The streamed device log (--record): rows written, dropped.
  const DeviceLogWriter& record() const { return record_; }

 private:
  std::string open_socket();
  void close_socket();
  void drain_backlog();
  void note_offset(double now, const udp::StatePacket& p) noexcept;
  double age(double now, const udp::StatePacket& p) const noexcept;
  static bool same_sender(const sockaddr_in& a, const sockaddr_in& b) noexcept;
  void take(const udp::StatePacket& p, const sockaddr_in& from);
  bool send_force(double now, const DeviceCommand& cmd, bool& broken) noexcept;
  bool send_datagram(const std::uint8_t* data, std::size_t n, bool& broken) noexcept;

  DeviceOptions opt_;
  UdpEndpoint bind_;
  int fd_ = -1;
  std::uint16_t local_port_ = 0;

  // Newest valid sample taken and where it came from.
  bool have_sample_ = false;
  udp::StatePacket newest_;
  DeviceState state_;
  sockaddr_in peer_{};
  // The rig's clock against the loop's: the smallest offset (now - device_time) seen this
  // session, and the loop time it was last updated.
  bool have_offset_ = false;
  double min_offset_ = 0.0, offset_time_ = 0.0;
  double taken_time_ = 0.0;  // loop time the newest sample was taken
  bool recorded_newest_ = true;  ///< the newest sample's row is already in the log

  alignas(8) std::array<std::uint8_t, 2048> rx_{};
  alignas(8) std::array<std::uint8_t, udp::kMaxForcePacketBytes> tx_{};
  alignas(8) std::array<std::uint8_t, udp::kMaxTactilePacketBytes> tactile_tx_{};
  DeviceLogWriter record_;
};

/// The registry's factory for driver "udp". Throws std::invalid_argument naming `udp_bind` for
/// a bad HOST:PORT (and `fingers` for a finger count outside kMinFingers..kMaxFingers).
std::unique_ptr<Device> make_udp_device(const DeviceOptions& opt);

}  // namespace hapticloth::devices
