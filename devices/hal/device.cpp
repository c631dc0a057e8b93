#include "hal/device.hpp"

#include <cmath>

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

const char* to_string(Status s) {
  switch (s) {
    case Status::Ok: return "ok";
    case Status::NoData: return "no_data";
    case Status::Error: return "error";
  }
  return "?";
}

const char* to_string(Lifecycle s) {
  switch (s) {
    case Lifecycle::Unconfigured: return "unconfigured";
    case Lifecycle::Inactive: return "inactive";
    case Lifecycle::Active: return "active";
    case Lifecycle::Failed: return "failed";
  }
  return "?";
}

}  // namespace hapticloth::devices
