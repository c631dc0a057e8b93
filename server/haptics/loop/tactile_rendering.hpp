// The haptic loop's tactile half: per fingertip, where on the fabric it is (a WeaveTracker fed
// by each global step's contact and the finger pad's slip) and what its skin feels there (a TactileChannel: the vibration
// block and the pin frame), written as the device's TactileCommand. Made only for a device that
// declares a tactile display and a cloth whose material has a [surface]; otherwise the loop
// has none and spends nothing on it. render() allocates nothing.
#pragma once

#include <array>
#include <memory>

#include "cloth/model.hpp"
#include "hal/tactile.hpp"
#include "haptics/sim/handoff.hpp"
#include "tactile/tactile_channel.hpp"
#include "tactile/weave_tracker.hpp"

namespace hapticloth::haptics {

/// What the tactile half did so far (read off the real-time thread after the run).
struct TactileCounters {
  std::uint64_t frames = 0;          ///< ticks rendered
  std::uint64_t textured_ticks = 0;  ///< finger-ticks with a non-zero vibration
  std::uint64_t slip_ticks = 0;      ///< finger-ticks on which the skin slipped
};

/// One finger's place on the fabric this tick (for observers).
struct TactilePlace {
  bool touching = false;
  double u = 0.0, v = 0.0;  ///< m, material coordinates
  double normal_force = 0.0;
};

class TactileRendering {
 public:
  /// Throws std::invalid_argument if the material has no surface or the capability is unusable.
  TactileRendering(const cloth::ClothModel& model, const devices::TactileCapability& cap, int fingers,
                   double tick_s, double finger_radius);

  /// One tick: each present finger's tactile frame from the snapshot's contact, the tick's
  /// report and the fingertip's velocity. Real-time safe.
  void render(const ClothSnapshot& s, const HapticReport& r, double now, double dt,
              devices::TactileCommand& out) noexcept;

  const TactileCounters& counters() const { return c_; }
  const TactilePlace& place(int f) const { return place_[f]; }
  const devices::TactileCapability& capability() const { return cap_; }

 private:
  tactile::WeaveAnchor anchor(const ClothSnapshot& s, const FingerReport& r, int f) const noexcept;
  Vec3 pad_velocity(const FingerReport& r, int f, double dt) const noexcept;

  const cloth::ClothModel& model_;
  devices::TactileCapability cap_;
  int fingers_;
  double radius_;
  std::array<std::unique_ptr<tactile::TactileChannel>, kMaxFingers> channel_;
  std::array<tactile::WeaveTracker, kMaxFingers> tracker_;
  std::array<TactilePlace, kMaxFingers> place_{};
  std::array<Vec3, kMaxFingers> last_proxy_{};  // the proxy on the last tick, m
  std::array<bool, kMaxFingers> had_contact_{};
  tactile::TactileOutput scratch_;
  TactileCounters c_;
};

}  // namespace hapticloth::haptics
