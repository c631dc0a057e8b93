// SIGINT and SIGTERM ask the server to stop: the session ends at its next haptic tick, zero
// force goes through the safety gate to the device, the device is deactivated, its record and
// the LCM log are flushed and closed, a `stopped` event is published, the summary printed, and
// the server exits 0. A second signal exits at once (status 128 + signal), without any of that.
#pragma once

#include <atomic>

namespace hapticloth::app {

/// Installs the handlers (also over an inherited "ignore", as a shell gives a background job)
/// and returns the flag they set. The handler only stores to a lock-free atomic, or calls
/// _exit on the second signal: both are async-signal-safe.
const std::atomic<bool>& install_stop_signals();

/// The signal that asked to stop (0 if none yet).
int stop_signal();

}  // namespace hapticloth::app
