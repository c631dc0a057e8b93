// SIGINT and SIGTERM ask the server to stop.
// - During set-up (reading the scene, building the model, opening the device and the
//   transports) nothing has run and nothing needs closing: the first signal exits at once with
//   status 0 and one line on stderr ("stopped by SIGINT during set-up").
// - From the preroll on (wind_down_on_stop_signals), the run winds down: the preroll ends, the
//   session ends at its next haptic tick, zero force goes through the safety gate to the device,
//   the device is deactivated, its record and the LCM log are flushed and closed, a `stopped`
//   event is published, the summary printed, and the server exits 0. A headless run stops at
//   its next step and prints its summary.
// A second signal exits at once (status 128 + signal), without any of that.
#pragma once

#include <atomic>

namespace hapticloth::app {

/// Installs the handlers (also over an inherited "ignore", as a shell gives a background job)
/// and returns the flag they set. The handler only stores to lock-free atomics, write()s a
/// fixed line, or calls _exit: each is async-signal-safe.
const std::atomic<bool>& install_stop_signals();

/// Set-up is over: from now on a first signal sets the flag and the run winds down.
void wind_down_on_stop_signals();

/// The signal that asked to stop (0 if none yet).
int stop_signal();

}  // namespace hapticloth::app
