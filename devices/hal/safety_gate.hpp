// The one gate every force passes before any driver sees it (libfranka style): non-finite ->
// zero and a counted event; clamp to the device's maximum force; slew-rate limit; watchdog:
// when the device state is older than the watchdog time the forces ramp to zero and the device
// is reported stale, and they ramp back when fresh state returns. The tactile output passes the
// same gate: non-finite -> zero, clamped to the display's limits, faded with the forces.
// Real-time safe.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>

#include "hal/device.hpp"

namespace hapticloth::devices {

struct GateConfig {
  double max_force = 0.0;      ///< N per finger; 0 = the device's max_force (never above it)
  double slew_rate = 1000.0;   ///< N/s: largest change of a force component per second
  double watchdog = 0.005;     ///< s: state older than this is stale
  double ramp_time = 0.02;     ///< s: forces fade out (stale) and back in (fresh) over this
};

struct GateCounters {
  std::uint64_t commands = 0;
  std::uint64_t non_finite = 0;    ///< forces replaced by zero
  std::uint64_t clamped = 0;       ///< forces clamped to max_force
  std::uint64_t slew_limited = 0;  ///< forces whose change was limited
  std::uint64_t stale_events = 0;  ///< fresh -> stale transitions
  std::uint64_t stale_ticks = 0;   ///< commands issued while stale
  std::uint64_t tactile_commands = 0;
  std::uint64_t tactile_non_finite = 0;  ///< tactile samples or pins replaced by zero
  std::uint64_t tactile_clamped = 0;     ///< tactile samples or pins clamped to the display's limit
};

class SafetyGate {
 public:
  /// Throws std::invalid_argument for a configuration that is not finite and positive.
  SafetyGate(const DeviceInfo& info, const GateConfig& cfg = {});

  /// `now`: loop clock (s); `state_time`: loop time the newest device state arrived (< 0:
  /// never). Writes the gated command to `out` (flags set: stale, clamped, fault).
  void apply(double now, double state_time, const DeviceCommand& in, DeviceCommand& out) noexcept;
  /// The tick's tactile output, after apply() of the same tick: each vibration sample within
  /// +-max_vibration and each pin within +-max_pin (the device's TactileCapability), non-finite
  /// values zero, all scaled by the stale fade (gain()), as the forces are.
  void apply_tactile(const TactileCommand& in, TactileCommand& out) noexcept;

  /// True if a device state that arrived at loop time `state_time` (< 0: never) is fresh at
  /// `now`: the watchdog's test, which apply() uses too.
  bool fresh(double now, double state_time) const noexcept {
    return state_time >= 0.0 && std::isfinite(now) && now - state_time <= watchdog_;
  }
  bool stale() const { return stale_; }
  /// Fade factor in [0, 1] applied to the forces (0 while fully stale).
  double gain() const { return gain_; }
  const GateCounters& counters() const { return c_; }
  double max_force() const { return max_force_; }
  /// Back to the initial state: stale, zero force (for reactivation).
  void reset();

 private:
  int fingers_;
  TactileCapability tactile_;
  double max_force_, slew_, watchdog_, ramp_, nominal_dt_;
  double last_now_ = -1.0;
  double gain_ = 0.0;
  bool stale_ = true;
  std::array<Vec3, kMaxFingers> prev_{};
  std::array<Vec3, kMaxFingers> held_{};  // the last force asked while fresh (clamped, finite)
  GateCounters c_;
};

}  // namespace hapticloth::devices
