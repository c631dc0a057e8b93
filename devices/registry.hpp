// The one place drivers are registered. The server picks a driver by name from configuration.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "hal/device.hpp"
#include "hal/options.hpp"

namespace hapticloth::devices {

using DeviceFactory = std::function<std::unique_ptr<Device>(const DeviceOptions&)>;

/// Names of the registered drivers, sorted.
std::vector<std::string> device_names();

/// Whether the driver named `driver` streams on its own clock and can pace the haptic loop
/// (Device::paces_loop; [device] clock = "device"). False for an unknown name.
bool driver_paces_loop(const std::string& driver);

/// Creates the driver named opt.driver. Throws std::invalid_argument listing the known
/// drivers for an unknown name (never a silent default).
std::unique_ptr<Device> make_device(const DeviceOptions& opt);

}  // namespace hapticloth::devices
