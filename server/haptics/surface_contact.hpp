// How a fingertip touches the cloth on the haptic thread: one interface, one implementation per
// surface model (ProxyContact: the proxies solved with the global cloth, direct coupling;
// PatchContact: the local refinement of section 4.2).
#pragma once

#include "haptics/handoff.hpp"

namespace hapticloth::haptics {

/// The fingertip of one finger for one tick, in the scene frame.
struct Fingertip {
  int finger = 0;
  Vec3 centre = Vec3::Zero();    ///< the device's fingertip, m
  Vec3 velocity = Vec3::Zero();  ///< m/s
};

class SurfaceContact {
 public:
  virtual ~SurfaceContact() = default;
  /// The contact of fingertip `tip` with the cloth of snapshot `s` at loop time `now` (the tick
  /// `tick_dt` after the previous one): fills `out` (force on the user, proxy, contact).
  /// Real-time safe: no allocation, no lock.
  virtual void touch(const ClothSnapshot& s, double now, double tick_dt, const Fingertip& tip,
                     FingerReport& out) noexcept = 0;
  /// The finger left (no fresh device sample): forget its contact state, so that it starts
  /// afresh where the device puts it when it comes back.
  virtual void release(int finger) noexcept { (void)finger; }
};

}  // namespace hapticloth::haptics
