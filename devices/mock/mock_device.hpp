// The mock two-finger device: fingertips follow a scripted trajectory on the loop clock (so it
// runs in real time under the real-time loop and as fast as possible under a simulated clock),
// and it records every force it receives (streamed to the device log, DeviceOptions::record_path)
// and, with a tactile display (DeviceOptions::tactile), the tactile output in memory.
#pragma once

#include <array>
#include <memory>
#include <vector>

#include "hal/device.hpp"
#include "hal/options.hpp"
#include "log/device_log.hpp"
#include "mock/trajectory.hpp"

namespace hapticloth::devices {

/// The tactile output a mock device received: every vibration sample per finger (room for
/// kTactileRecordSeconds, made at activate; samples beyond are counted, not kept), and the last
/// pin frame.
struct TactileRecord {
  static constexpr double kTactileRecordSeconds = 120.0;
  std::uint64_t frames = 0, dropped_samples = 0;
  std::array<std::vector<float>, kMaxFingers> vibration;
  TactileCommand last;
};

class MockDevice final : public DeviceDriver {
 public:
  explicit MockDevice(const DeviceOptions& opt);
  /// With a trajectory given directly (tests).
  MockDevice(const DeviceOptions& opt, Trajectory tr);

  // The Device interface (hal/device.hpp).
  std::string configure() override;
  std::string activate() override;
  void deactivate() override;
  Status read(double now, DeviceState& state) noexcept override;
  Status write(double now, const DeviceCommand& cmd) noexcept override;
  Status write_tactile(double now, const TactileCommand& cmd) noexcept override;
  const TactileRecord& tactile_record() const { return tactile_; }

  /// The streamed device log (--record): rows written, dropped.
  const DeviceLogWriter& record() const { return record_; }
  const Trajectory& trajectory() const { return tr_; }
  /// Trajectory time of the loop time `now` (0 at the first read after activate).
  double script_time(double now) const { return t0_ < 0.0 ? 0.0 : now - t0_; }

 private:
  DeviceOptions opt_;
  Trajectory tr_;
  bool have_tr_ = false;
  double t0_ = -1.0;
  DeviceState last_;
  DeviceLogWriter record_;
  TactileRecord tactile_;
};

std::unique_ptr<Device> make_mock_device(const DeviceOptions& opt);

}  // namespace hapticloth::devices
