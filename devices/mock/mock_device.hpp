// The mock two-finger device: fingertips follow a scripted trajectory on the loop clock (so it
// runs in real time under the real-time loop and as fast as possible under a simulated clock),
// and it records every force it receives (streamed to the device log, DeviceOptions::record_path).
#pragma once

#include <memory>

#include "hal/device.hpp"
#include "hal/options.hpp"
#include "log/device_log.hpp"
#include "mock/trajectory.hpp"

namespace hapticloth::devices {

class MockDevice final : public Device {
 public:
  explicit MockDevice(const DeviceOptions& opt);
  /// With a trajectory given directly (tests).
  MockDevice(const DeviceOptions& opt, Trajectory tr);

  // The Device interface (hal/device.hpp), which every driver declares the same way.
  const DeviceInfo& info() const override { return info_; }
  std::string configure() override;
  std::string activate() override;
  void deactivate() override;
  Status read(double now, DeviceState& state) noexcept override;
  Status write(double now, const DeviceCommand& cmd) noexcept override;
  const DeviceCounters& counters() const override { return counters_; }

  /// The streamed device log (--record): rows written, dropped.
  const DeviceLogWriter& record() const { return record_; }
  const Trajectory& trajectory() const { return tr_; }
  /// Trajectory time of the loop time `now` (0 at the first read after activate).
  double script_time(double now) const { return t0_ < 0.0 ? 0.0 : now - t0_; }

 private:
  DeviceOptions opt_;
  DeviceInfo info_;
  Trajectory tr_;
  bool have_tr_ = false;
  double t0_ = -1.0;
  DeviceState last_;
  DeviceCounters counters_;
  DeviceLogWriter record_;
};

std::unique_ptr<Device> make_mock_device(const DeviceOptions& opt);

}  // namespace hapticloth::devices
