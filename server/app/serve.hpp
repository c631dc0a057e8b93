// Running a scene with a haptic device: the global simulation and the 1 kHz haptic loop.
#pragma once

#include <atomic>
#include <iosfwd>
#include <string>

#include "app/scene_file.hpp"
#include "registry.hpp"
#include "transport/options.hpp"

namespace hapticloth::app {

struct ServeOptions {
  double duration = -1.0;  ///< s; < 0: the scene's duration
  bool realtime = true;    ///< false: stepped clock, as fast as possible (tests, replays)
  bool json = false;
  /// State over zenoh / LCM (server/transport). A zenoh endpoint that cannot be opened is
  /// fatal if transport_required, else the server runs without zenoh and says so.
  transport::TransportOptions transport;
  bool transport_required = false;
  /// Set by a stop signal (install_stop_signals): the preroll and the session end at once,
  /// the summary says so.
  const std::atomic<bool>* stop = nullptr;
  /// Makes the driver from scene.device; empty: the registry's (devices::make_device). Tests
  /// give their own, such as a device that fails during the session.
  devices::DeviceFactory make_device;
};

/// Settles the scene for its preroll, starts the device and the session, runs, and prints what
/// it did (stages on and why, loop statistics, contacts, device and gate counters).
/// Returns 0, or 1 if the device failed during the session or its record could not be written
/// (either said on stderr). Throws ConfigError / std::runtime_error on bad set-up.
int serve(Scene scene, const ServeOptions& opt, std::ostream& out);

}  // namespace hapticloth::app
