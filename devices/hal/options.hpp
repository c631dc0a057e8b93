// Configuration of a device driver, from the command line (--device ...) and the scene's
// [device] table. One struct for every driver; each driver reads the fields it needs and
// rejects a configuration it cannot use with a message naming the field.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "hal/device.hpp"

namespace hapticloth::devices {

inline constexpr int kDefaultUdpPort = 47800;

struct DeviceOptions {
  std::string driver = "mock";        ///< registered driver name: mock, udp, replay
  int fingers = 2;
  Box workspace;                      ///< m, device frame
  double max_force = 5.0;             ///< N per finger
  double max_stiffness = 2000.0;      ///< N/m
  double rate = 1000.0;               ///< Hz, nominal
  TactileCapability tactile;          ///< the tactile display (mock, udp: the scene's [device.tactile])

  // mock
  std::string script;                 ///< trajectory file (.toml or .csv); empty: built-in demo
  std::string record_path;            ///< device log CSV written at deactivate (mock, udp)

  // udp
  std::string udp_bind = "127.0.0.1:" + std::to_string(kDefaultUdpPort);  ///< HOST:PORT
  /// s: a sample older than this when it is read, by the rig's clock, is dropped as stale (the
  /// safety gate's watchdog: the scene's [haptics] watchdog_ms)
  double stale_after = 0.005;
  /// s: a composite's part that went stale fades its finger's force out over this (the safety
  /// gate's ramp: [haptics] ramp_ms)
  double stale_ramp = 0.02;

  // composite: the parts, one finger each (part i gives finger i)
  std::vector<DeviceOptions> parts;

  // replay
  std::string replay_path;            ///< device log CSV to play back
};

/// The DeviceInfo of a driver whose limits come from the options (mock, replay, remote, udp).
inline DeviceInfo device_info(const DeviceOptions& o, std::string name) {
  return {.name = std::move(name),
          .fingers = o.fingers,
          .workspace = o.workspace,
          .max_force = o.max_force,
          .max_stiffness = o.max_stiffness,
          .nominal_rate = o.rate,
          .tactile = o.tactile};
}

}  // namespace hapticloth::devices
