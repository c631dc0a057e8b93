// The replay device: plays a recorded device log (the mock's, the UDP driver's or the fake
// rig's) back as device state, on the loop clock. The recorded forces stay available so that a
// replay test can compare what the server renders now with what it rendered then.
#pragma once

#include <memory>
#include <vector>

#include "hal/device.hpp"
#include "hal/options.hpp"
#include "log/device_log.hpp"
#include "mock/trajectory.hpp"

namespace hapticloth::devices {

class ReplayDevice final : public DeviceDriver {
 public:
  explicit ReplayDevice(const DeviceOptions& opt);

  std::string configure() override;
  std::string activate() override;
  void deactivate() override {}
  Status read(double now, DeviceState& state) noexcept override;
  Status write(double now, const DeviceCommand& cmd) noexcept override;

  /// The recorded force on `finger` nearest to log time t (N).
  Vec3 recorded_force(int finger, double t) const noexcept;
  double duration() const { return positions_.duration(); }

 private:
  DeviceOptions opt_;
  Trajectory positions_{2};
  std::vector<std::vector<LogRow>> rows_;  // per finger
  double t0_ = -1.0;
  DeviceState last_;
};

std::unique_ptr<Device> make_replay_device(const DeviceOptions& opt);

}  // namespace hapticloth::devices
