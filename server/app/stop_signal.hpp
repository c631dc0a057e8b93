// SIGINT and SIGTERM ask the server to stop.
// - During set-up (reading the scene, building the model, opening the device and the
//   transports) the flag is checked between the steps (check_stop): the server leaves with
//   StoppedDuringSetUp, exit 0 and one line on stderr, and no file it claimed stays behind.
//   Each step is bounded (the mesh by memory and the haptic budget: app/mesh_budget.hpp).
// - From the preroll on, the run winds down: the preroll ends, the session ends at its next
//   haptic tick, zero force goes through the safety gate to the device, the device is
//   deactivated, its record and the LCM log are flushed and closed, a `stopped` event is
//   published, the summary printed, and the server exits 0. A headless run stops at its next
//   step and prints its summary.
// A second signal exits at once (status 128 + signal), without any of that.
#pragma once

#include <atomic>
#include <stdexcept>

namespace hapticloth::app {

/// Installs the handlers (also over an inherited "ignore", as a shell gives a background job)
/// and returns the flag they set. The handler only stores to lock-free atomics or calls _exit:
/// both are async-signal-safe.
const std::atomic<bool>& install_stop_signals();

/// The signal that asked to stop (0 if none yet).
int stop_signal();
/// "SIGINT" or "SIGTERM", the signal that asked to stop.
const char* stop_signal_name();

/// A stop signal came during set-up: nothing ran.
struct StoppedDuringSetUp : std::runtime_error {
  StoppedDuringSetUp();
};
/// Throws StoppedDuringSetUp if `stop` is set (a null flag never is).
void check_stop(const std::atomic<bool>* stop);

}  // namespace hapticloth::app
