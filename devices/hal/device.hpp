// The haptic device hardware abstraction. The haptic loop depends on this interface only.
//
// Lifecycle (ros2_control style):  configure() -> activate() -> read()/write() at the loop rate
// -> deactivate(). configure/activate/deactivate run off the real-time path: they may allocate
// and return an error message. read() and write() run on the real-time path: they return a
// status, never throw, never allocate and never block. A device that streams on its own clock
// may also pace the loop (paces_loop, await_sample: the only blocking call).
//
// Device frame: right-handed, metres, origin at the workspace centre as the driver defines it;
// the server maps it to the scene with the scene's [device] axes and origin
// (haptics::DeviceMapping: a rotation and an origin). Forces are in newtons, in the same
// frame, applied to the user's fingertip.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <utility>

#include <Eigen/Core>

#include "hal/limits.hpp"
#include "hal/tactile.hpp"

namespace hapticloth::devices {

using Vec3 = Eigen::Vector3d;


struct Box {
  Vec3 min{-0.1, -0.1, -0.1};
  Vec3 max{0.1, 0.1, 0.1};
  bool contains(const Vec3& p) const {
    return (p.array() >= min.array()).all() && (p.array() <= max.array()).all();
  }
};

struct DeviceInfo {
  std::string name;
  int fingers = 2;                 ///< two or more
  Box workspace;                   ///< m, device frame
  double max_force = 5.0;          ///< N per finger
  double max_stiffness = 2000.0;   ///< N/m: stiffest spring the device renders stably
  double nominal_rate = 1000.0;    ///< Hz
  TactileCapability tactile;       ///< its tactile display, if any (hal/tactile.hpp)
};

inline bool valid_finger_count(int n) { return n >= kMinFingers && n <= kMaxFingers; }

/// The one check of what a device says it is (every driver, the handle and the safety gate use
/// it): empty if usable, else what is wrong, naming the field (`fingers`, `max_force`,
/// `max_stiffness`, `nominal_rate`, `workspace`, `tactile.*`).
std::string validate(const DeviceInfo& info);

struct FingerState {
  Vec3 position = Vec3::Zero();  ///< m, device frame
  Vec3 velocity = Vec3::Zero();  ///< m/s, device frame
  std::uint32_t buttons = 0;     ///< bit mask
};

/// One sample of the whole device.
struct DeviceState {
  double device_time = 0.0;    ///< s, the device's own clock (for logs)
  double received_time = -1.0; ///< s, loop clock when this sample arrived; < 0: never
  std::uint64_t sequence = 0;  ///< increases with every new sample
  std::array<FingerState, kMaxFingers> finger{};
  /// Bit f set: finger f has no fresh sample of its own though the device has (a composite
  /// device's part not heard from yet, or silent past its own watchdog). Its position means
  /// nothing; the loop treats the finger as absent.
  std::uint32_t absent = 0;
};

struct DeviceCommand {
  std::array<Vec3, kMaxFingers> force{};  ///< N, device frame, on the user's fingertip
  std::uint32_t flags = 0;                ///< CommandFlags
  DeviceCommand() {
    for (auto& f : force) f.setZero();
  }
};

enum CommandFlags : std::uint32_t {
  kFlagStale = 1u << 0,    ///< the server considers the device state stale (forces ramped out)
  kFlagClamped = 1u << 1,  ///< a force was clamped to the device's limit
  kFlagFault = 1u << 2,    ///< a non-finite force was replaced by zero
};

enum class Status : std::uint8_t {
  Ok,       ///< new state read / command written
  NoData,   ///< nothing new since the last read (the last state stays valid until stale)
  Error,    ///< the device failed: its handle turns Failed, the loop counts it and commands nothing more
};
const char* to_string(Status s);

enum class Lifecycle : std::uint8_t { Unconfigured, Inactive, Active, Failed };
const char* to_string(Lifecycle s);

/// Counters every driver keeps (monotonic, read by the loop's statistics).
struct DeviceCounters {
  std::uint64_t reads = 0, samples = 0, writes = 0;
  std::uint64_t dropped_malformed = 0;   ///< wrong size, magic or checksum, garbage
  std::uint64_t dropped_version = 0;     ///< protocol version not understood
  std::uint64_t dropped_duplicate = 0;   ///< a sequence number already seen
  std::uint64_t dropped_reordered = 0;   ///< older than the newest sample already taken
  std::uint64_t dropped_out_of_range = 0;  ///< non-finite or outside the workspace
  std::uint64_t dropped_backlog = 0;  ///< queued before the session started (drained at activate)
  std::uint64_t dropped_stale = 0;    ///< newest of a read, older than the watchdog by the device's clock
  std::uint64_t dropped_other_sender = 0;  ///< from another sender than the one the session took
  std::uint64_t send_errors = 0;
  std::uint64_t tactile_sent = 0;    ///< tactile packets sent (udp)
  std::uint64_t record_rows = 0;     ///< device-log rows written (--record; set at deactivate)
  std::uint64_t record_dropped = 0;  ///< device-log rows lost to a full buffer (--record)
  std::uint64_t dropped_total() const {
    return dropped_malformed + dropped_version + dropped_duplicate + dropped_reordered +
           dropped_out_of_range + dropped_backlog + dropped_stale + dropped_other_sender;
  }
};

struct GateCounters;  // hal/safety_gate.hpp

class Device {
 public:
  virtual ~Device() = default;

  /// Static description; valid after configure().
  virtual const DeviceInfo& info() const = 0;

  /// Off the real-time path. Opens files, sockets; returns an empty string on success, else
  /// the error (and the device stays Unconfigured).
  virtual std::string configure() = 0;
  /// Off the real-time path. Starts streaming. Empty string on success.
  virtual std::string activate() = 0;
  /// Off the real-time path. Stops streaming, sends zero forces where it can, flushes logs.
  virtual void deactivate() = 0;

  /// Real-time path. `now` is the loop clock in seconds. Fills `state` with the newest sample
  /// (Ok) or leaves it unchanged (NoData).
  virtual Status read(double now, DeviceState& state) noexcept = 0;
  /// Real-time path. The command has already passed the SafetyGate.
  virtual Status write(double now, const DeviceCommand& cmd) noexcept = 0;
  /// Real-time path, after write(), on a device whose info() declares a tactile display only:
  /// this tick's tactile output, through the SafetyGate too.
  virtual Status write_tactile(double now, const TactileCommand& cmd) noexcept {
    (void)now;
    (void)cmd;
    return Status::Ok;
  }

  /// Whether the device streams its samples on its own clock and can pace the loop (a tick
  /// per sample: DeviceClock). False for a device the loop polls (mock, replay).
  virtual bool paces_loop() const { return false; }
  /// Real-time path, for a device that paces the loop: blocks until a sample is ready to read()
  /// (true) or until `until` (CLOCK_MONOTONIC, s; false). The one call of the interface that
  /// blocks, by design; a device that does not pace returns false at once.
  virtual bool await_sample(double until) noexcept {
    (void)until;
    return false;
  }

  virtual const DeviceCounters& counters() const = 0;

  /// A device made of parts (composite/composite_device.hpp): how many, each part, and the
  /// counters of each part's own watchdog (null for a device without one). Off the real-time
  /// path (the summary).
  virtual int part_count() const { return 0; }
  virtual const Device& part(int i) const {
    (void)i;
    return *this;
  }
  virtual const GateCounters* part_gate(int i) const {
    (void)i;
    return nullptr;
  }
};

/// What every driver keeps: its description and its counters, which the Device interface reads.
class DeviceDriver : public Device {
 public:
  const DeviceInfo& info() const override { return info_; }
  const DeviceCounters& counters() const override { return counters_; }

 protected:
  DeviceDriver() = default;
  explicit DeviceDriver(DeviceInfo info) : info_(std::move(info)) {}

  DeviceInfo info_;
  DeviceCounters counters_;
};

}  // namespace hapticloth::devices
