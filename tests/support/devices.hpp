// Device descriptions shared by the HAL's tests (test_gate, test_handle).
#pragma once

#include "hal/device.hpp"

namespace hapticloth::test {

/// A two-finger device with the given force limit and the HAL's other defaults.
inline devices::DeviceInfo two_fingers(double max_force = 4.0) {
  devices::DeviceInfo i;
  i.name = "test";
  i.fingers = 2;
  i.max_force = max_force;
  return i;
}

}  // namespace hapticloth::test
