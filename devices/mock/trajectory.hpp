// Fingertip trajectories for the mock device: piecewise-linear keyframes per finger, from a CSV
// (time,finger,x,y,z), from a TOML script of primitives (approach, press, stroke, pinch, lift,
// release, hold, move), or the built-in demo. Evaluation is allocation-free.
#pragma once

#include <string>
#include <vector>

#include "hal/device.hpp"

namespace hapticloth::devices {

struct Keyframe {
  double t;
  Vec3 p;
};

class Trajectory {
 public:
  explicit Trajectory(int fingers = 2) : keys_(fingers) {}
  int fingers() const { return static_cast<int>(keys_.size()); }
  /// Appends a keyframe; times per finger must not decrease (throws std::invalid_argument).
  void add(int finger, double t, const Vec3& p);
  /// Position and velocity at time t (clamped to the first/last keyframe: at rest outside).
  void evaluate(int finger, double t, Vec3& p, Vec3& v) const noexcept;
  /// The next sample of a device that plays this trajectory: every finger at script time t,
  /// read at loop time `now` (the mock and the replay device).
  void sample(int fingers, double t, double now, DeviceState& s) const noexcept;
  double duration() const;
  const std::vector<Keyframe>& keys(int finger) const { return keys_[finger]; }
  /// Throws std::invalid_argument naming the first keyframe outside the box.
  void check_inside(const Box& b, const std::string& source) const;
  /// Throws std::invalid_argument naming `source`, the finger and the times if a fingertip
  /// moves faster than `max_speed` (m/s) between two keyframes (a jump).
  void check_speed(double max_speed, const std::string& source) const;

 private:
  std::vector<std::vector<Keyframe>> keys_;
};

/// Fastest fingertip a mock script may ask for, m/s: a hand moves at up to about 2 m/s; a
/// faster step is a jump (a typo in a position or a time), which the server would render as an
/// impact no person can make.
inline constexpr double kMaxScriptSpeed = 5.0;

/// CSV `time,finger,x,y,z` (m, device frame). Errors: "PATH:LINE: message".
Trajectory load_trajectory_csv(const std::string& path, int fingers);

/// TOML script:
///   [start]  finger0 = [x, y, z]  finger1 = [x, y, z]     (m)
///   [[step]] primitive = "approach" | "press" | "stroke" | "pinch" | "lift" | "release" |
///            "hold" | "move", duration = s, and the primitive's parameters (docs/devices.md).
/// Errors: "PATH:LINE: key 'step[2].depth': message".
Trajectory load_trajectory_toml(const std::string& path, int fingers);

/// .csv or .toml by extension.
Trajectory load_trajectory(const std::string& path, int fingers);

/// The built-in demo: two fingers 4 cm apart, 3 cm above the origin, approach, press,
/// stroke, pinch, lift, release.
Trajectory demo_trajectory(int fingers);

}  // namespace hapticloth::devices
