// A device made of parts: a rig of single-finger devices (two haptic arms for a pinch, each
// with its own UDP stream) is one device of as many fingers to the haptic loop. Part i gives
// finger i. Each part keeps its own counters and its own watchdog: a part whose samples stop
// has its finger's force faded out over the ramp (its own SafetyGate, stale after the scene's
// watchdog), while the others go on; the loop's gate sees the device stale only when every
// part is. The parts are UDP drivers of one finger (devices/udp); the scene names them in
// [[device.part]] tables.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "hal/device.hpp"
#include "hal/options.hpp"
#include "hal/safety_gate.hpp"

namespace hapticloth::devices {

class CompositeDevice final : public DeviceDriver {
 public:
  /// Throws std::invalid_argument naming the part and field for a configuration it cannot use
  /// (fewer than two parts, a part that is not a one-finger streaming driver, a bad udp_bind).
  explicit CompositeDevice(const DeviceOptions& opt);

  // The Device interface (hal/device.hpp).
  std::string configure() override;
  std::string activate() override;
  void deactivate() override;
  Status read(double now, DeviceState& state) noexcept override;
  Status write(double now, const DeviceCommand& cmd) noexcept override;
  Status write_tactile(double now, const TactileCommand& cmd) noexcept override;
  int part_count() const override { return static_cast<int>(parts_.size()); }
  const Device& part(int i) const override { return *parts_[static_cast<std::size_t>(i)].device; }
  const GateCounters* part_gate(int i) const override { return &parts_[static_cast<std::size_t>(i)].gate.counters(); }

 private:
  struct Part {
    std::unique_ptr<Device> device;
    SafetyGate gate;         // the part's own watchdog, fade and counters
    DeviceState state;       // its newest sample (one finger)
  };
  template <class Send>
  Status to_each_part(Send&& send) noexcept;
  void sum_counters() noexcept;

  std::vector<Part> parts_;
  DeviceState state_;
};

std::unique_ptr<Device> make_composite_device(const DeviceOptions& opt);

}  // namespace hapticloth::devices
