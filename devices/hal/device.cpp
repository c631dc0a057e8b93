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
