// What a device's tactile display takes (issue: the paper's tactile half): per fingertip, a
// block of vibration samples each tick and a pin-array frame. HAPTEX drove a 6 x 4 grid of
// piezo contactors at 2 mm pitch per fingertip, 20-400 Hz. A device declares what it has
// (TactileCapability in DeviceInfo); a device without a tactile display declares nothing and the
// loop computes and sends nothing for it.
#pragma once

#include <array>
#include <cstdint>
#include <string>

#include "hal/limits.hpp"

namespace hapticloth::devices {

inline constexpr int kMaxTactileSamples = 16;  ///< vibration samples a tick: 16 kHz at 1 kHz
inline constexpr int kMaxPins = 64;            ///< pins per fingertip

struct TactileCapability {
  int vibration_rate = 0;       ///< Hz, samples a second per finger (a multiple of the tick rate); 0: none
  int pin_rows = 0, pin_cols = 0;  ///< the pin array; 0 x 0: none
  double pin_pitch = 0.002;     ///< m between pins
  double max_vibration = 1e-4;  ///< m: largest vibration displacement the actuator takes
  double max_pin = 1e-3;        ///< m: largest pin displacement
  bool vibration() const { return vibration_rate > 0; }
  bool pins() const { return pin_rows > 0 && pin_cols > 0; }
  bool any() const { return vibration() || pins(); }
};

/// Empty if usable on a device ticking at `nominal_rate`, else what is wrong, naming the field
/// (`tactile.vibration_rate`, `tactile.pins`, `tactile.pin_pitch`, `tactile.max_vibration`,
/// `tactile.max_pin`).
std::string validate(const TactileCapability& c, double nominal_rate);

/// One fingertip's tactile output for one tick.
struct TactileFrame {
  int samples = 0;                                    ///< vibration samples this tick
  std::array<float, kMaxTactileSamples> vibration{};  ///< m, skin displacement, oldest first
  int rows = 0, cols = 0;                             ///< the pin frame's shape
  std::array<float, kMaxPins> pins{};                 ///< m, row-major: row i along the warp, column j along the weft
};

enum TactileFlags : std::uint32_t {
  kTactileClamped = 1u << 0,  ///< a sample or pin was clamped to the display's limit
  kTactileFault = 1u << 1,    ///< a non-finite sample or pin was replaced by zero
  kTactileFaded = 1u << 2,    ///< scaled down by the safety gate's stale fade
};

/// The whole device's tactile output for one tick (the command's tactile half).
struct TactileCommand {
  std::array<TactileFrame, kMaxFingers> finger{};
  std::uint32_t flags = 0;               ///< TactileFlags
};

}  // namespace hapticloth::devices
