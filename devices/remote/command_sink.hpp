// Where fingertip trajectory commands from the network go. The RemoteDevice implements it; the
// transport Hub holds a pointer to it (set by the server when the device is "remote") and hands
// it every trajectory command it receives over zenoh or LCM.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "hal/device.hpp"

namespace hapticloth::devices {

/// One finger's piecewise-linear trajectory, device frame.
struct TrajectoryCommand {
  int finger = 0;                ///< 0-based
  std::vector<double> times;     ///< s after the device takes the command; >= 0, increasing
  std::vector<Vec3> positions;   ///< m, device frame, one per time
  std::string source;            ///< who sent it (for events)
  std::int64_t seq = 0;          ///< the sender's sequence number
  /// The sender's send time (trajectory_cmd_t utime). Commands of one source with the same
  /// utime are one batch and start together (RemoteDevice); 0: on its own.
  std::int64_t utime = 0;
};

class RemoteCommandSink {
 public:
  virtual ~RemoteCommandSink() = default;
  /// Any thread but the real-time one; thread-safe. Validates the command and, if it is
  /// valid, hands it to the real-time side (lock-free). Returns "" if accepted, else the
  /// reason it was rejected (the command is then ignored).
  virtual std::string submit(const TrajectoryCommand& cmd) = 0;
  /// Fastest fingertip speed a command may ask for, m/s (> 0).
  virtual void set_max_speed(double metres_per_second) = 0;
  virtual double max_speed() const = 0;
};

}  // namespace hapticloth::devices
