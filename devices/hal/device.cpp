#include "hal/device.hpp"

#include <cmath>
#include <cstddef>
#include <iterator>

namespace hapticloth::devices {

std::string validate(const DeviceInfo& i) {
  auto positive = [](double v) { return v > 0.0 && std::isfinite(v); };
  if (!valid_finger_count(i.fingers))
    return "fingers " + std::to_string(i.fingers) + ": a device has " + std::to_string(kMinFingers) +
           " to " + std::to_string(kMaxFingers);
  if (!positive(i.max_force)) return "max_force must be finite and > 0 (N)";
  if (!positive(i.max_stiffness)) return "max_stiffness must be finite and > 0 (N/m)";
  if (!positive(i.nominal_rate)) return "nominal_rate must be finite and > 0 (Hz)";
  if (!(i.workspace.max.array() > i.workspace.min.array()).all()) return "workspace: the box is empty";
  return validate(i.tactile, i.nominal_rate);
}

std::string validate(const TactileCapability& c, double nominal_rate) {
  if (c.vibration_rate < 0) return "tactile.vibration_rate must be >= 0 (Hz; 0: no vibration)";
  if (c.vibration()) {
    const double per_tick = c.vibration_rate / nominal_rate;
    if (std::abs(per_tick - std::round(per_tick)) > 1e-9 || per_tick < 1.0 || per_tick > kMaxTactileSamples)
      return "tactile.vibration_rate " + std::to_string(c.vibration_rate) + " Hz must be 1 to " +
             std::to_string(kMaxTactileSamples) + " whole samples per tick at " + std::to_string(nominal_rate) + " Hz";
  }
  if (c.pin_rows < 0 || c.pin_cols < 0 || c.pin_rows * c.pin_cols > kMaxPins)
    return "tactile.pins " + std::to_string(c.pin_rows) + " x " + std::to_string(c.pin_cols) +
           ": rows x columns must be 0 to " + std::to_string(kMaxPins);
  if ((c.pin_rows > 0) != (c.pin_cols > 0)) return "tactile.pins: rows and columns must both be 0 or both be > 0";
  auto positive = [](double v) { return v > 0.0 && std::isfinite(v); };
  if (!positive(c.pin_pitch)) return "tactile.pin_pitch must be finite and > 0 (m)";
  if (!positive(c.max_vibration)) return "tactile.max_vibration must be finite and > 0 (m)";
  if (!positive(c.max_pin)) return "tactile.max_pin must be finite and > 0 (m)";
  return "";
}

namespace {

// The name of an enumerator of an enum counted from 0, from the list of names in order.
template <class E, std::size_t N>
const char* name_of(E e, const char* const (&names)[N]) {
  const auto i = static_cast<std::size_t>(e);
  return i < N ? names[i] : "?";
}

constexpr const char* kStatusNames[] = {"ok", "no_data", "error"};
static_assert(std::size(kStatusNames) == static_cast<std::size_t>(Status::Error) + 1);
constexpr const char* kLifecycleNames[] = {"unconfigured", "inactive", "active", "failed"};
static_assert(std::size(kLifecycleNames) == static_cast<std::size_t>(Lifecycle::Failed) + 1);

}  // namespace

const char* to_string(Status s) { return name_of(s, kStatusNames); }

const char* to_string(Lifecycle s) { return name_of(s, kLifecycleNames); }

}  // namespace hapticloth::devices
