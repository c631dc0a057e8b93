// The remote device ("remote"): fingertips follow trajectories that clients inject over the
// network (trajectory_cmd_t over zenoh or LCM, through the transport Hub). It is a device like
// any other for the haptic loop: the same HAL, the same safety gate; the forces it is sent are
// published with the haptic state.
//
// Commands arrive on any thread through RemoteCommandSink::submit, are validated there, and
// reach the real-time side through one lock-free latest-value slot per finger. read() and
// write() take no lock and never allocate.
//
// Before any command, finger f rests where its script starts (DeviceOptions::script, the same
// files as the mock device's: the scene's [device] script or --script), or without one where
// the built-in demo trajectory starts. Only the first keyframe is used: a remote finger moves
// only when a client says so. A new command replaces the finger's trajectory: from where the finger is when
// read() takes it, a straight line to the first point (reached at times[0]), then the points,
// then it holds the last one.
#pragma once

#include <array>
#include <atomic>
#include <memory>
#include <mutex>
#include <vector>

#include "hal/device.hpp"
#include "hal/options.hpp"
#include "remote/command_sink.hpp"
#include "hal/rt_handoff.hpp"

namespace hapticloth::devices {

class RemoteDevice final : public DeviceDriver, public RemoteCommandSink {
 public:
  static constexpr int kMaxPoints = 4096;     ///< points per command
  /// m: how far the first point may be from the finger's position at submit() beyond what the
  /// speed limit allows (the finger moves for up to one tick, 1 mm at 1 m/s and 1 kHz, before
  /// the real-time side takes the command).
  static constexpr double kStartTolerance = 1e-3;

  explicit RemoteDevice(const DeviceOptions& opt);

  // The Device interface (hal/device.hpp).
  std::string configure() override;
  std::string activate() override;
  void deactivate() override;
  Status read(double now, DeviceState& state) noexcept override;
  Status write(double now, const DeviceCommand& cmd) noexcept override;

  std::string submit(const TrajectoryCommand& cmd) override;
  void set_max_speed(double v) override;
  double max_speed() const override { return max_speed_.load(std::memory_order_relaxed); }

  /// Commands the real-time side has taken so far.
  std::uint64_t commands_taken() const { return taken_.load(std::memory_order_relaxed); }
  /// The last force command written (device frame, N), for tests; real-time thread's copy.
  const DeviceCommand& last_command() const { return last_cmd_; }

 private:
  struct Plan {
    int n = 0;
    std::vector<double> t;
    std::vector<Vec3> p;
    std::uint64_t batch = 0;  // source and utime: the commands sent together (0: none)
  };
  struct Follow {            // real-time side, one per finger
    const Plan* plan = nullptr;
    double t0 = 0.0;         // loop time of the plan's time 0
    double leg_from = 0.0;   // plan time the first leg starts (> 0: taken late in its batch)
    int seg = 0;
    Vec3 start = Vec3::Zero();
  };
  std::string validate(const TrajectoryCommand& cmd) const;
  void follow(int f, double now, FingerState& out) noexcept;
  void take(Follow& fo, double now, const FingerState& at) noexcept;

  DeviceOptions opt_;
  std::atomic<double> max_speed_{1.0};
  std::mutex submit_mu_;                          // writers of the slots (never the RT side)
  std::vector<std::unique_ptr<TripleBuffer<Plan>>> slot_;  // per finger
  std::array<Follow, kMaxFingers> follow_{};
  std::array<std::array<std::atomic<double>, 3>, kMaxFingers> where_{};  // RT -> validation
  std::atomic<std::uint64_t> taken_{0};
  std::uint64_t batch_ = 0;      // RT side: the batch taken last, and the loop time it started
  double batch_t0_ = 0.0;
  DeviceState last_;
  DeviceCommand last_cmd_;
};

std::unique_ptr<Device> make_remote_device(const DeviceOptions& opt);

}  // namespace hapticloth::devices
