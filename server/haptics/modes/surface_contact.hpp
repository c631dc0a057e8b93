// How a fingertip touches the cloth on the haptic thread: the haptic half of a rendering mode
// (rendering.hpp), one implementation per mode (ProxyContact: direct coupling, the proxies
// solved with the global cloth; ResponseContact: the multirate path's response model;
// PatchContact: its patch model, section 4.2).
#pragma once

#include <array>

#include "haptics/sim/handoff.hpp"
#include "haptics/modes/rendering.hpp"

namespace hapticloth::haptics {

/// The fingertip of one finger for one tick, in the scene frame.
struct Fingertip {
  int finger = 0;
  Vec3 centre = Vec3::Zero();    ///< the device's fingertip, m
  Vec3 velocity = Vec3::Zero();  ///< m/s
};

/// Where and how finger `out` touches, from the global step's proxy `r` (the contact point,
/// normal, triangle, slip), for a finger in contact or not (`in_contact`).
inline void report_proxy_contact(const ProxyResult& r, bool in_contact, double k, FingerReport& out) {
  out.in_contact = in_contact;
  out.slipping = in_contact && r.slipping;
  out.normal = r.normal;
  out.contact = r.contact;
  out.triangle = in_contact ? r.triangle : -1;
  for (int i = 0; i < 3; ++i) out.bary[i] = r.bary[i];
  out.stiffness = in_contact ? k : 0.0;
}

class SurfaceContact {
 public:
  virtual ~SurfaceContact() = default;
  /// The contact of fingertip `tip` with the cloth of snapshot `s` at loop time `now` (the tick
  /// `tick_dt` after the previous one): fills `out` (force on the user, proxy, contact).
  /// Real-time safe: no allocation, no lock.
  virtual void touch(const ClothSnapshot& s, double now, double tick_dt, const Fingertip& tip,
                     FingerReport& out) noexcept = 0;
  /// Before the fingers' touch() of a tick: every finger's fingertip (`present[f]` false: no
  /// device sample), for models that couple the fingers (a pinch).
  virtual void prepare(const ClothSnapshot& s, const std::array<Fingertip, kMaxFingers>& tips,
                       const std::array<bool, kMaxFingers>& present, int fingers) noexcept {
    (void)s, (void)tips, (void)present, (void)fingers;
  }
  /// The finger left (no fresh device sample): forget its contact state, so that it starts
  /// afresh where the device puts it when it comes back.
  virtual void release(int finger) noexcept { (void)finger; }
  /// The patch model's builds, and those whose springs were softened to stay stable (0 for the
  /// other modes).
  virtual std::uint64_t patch_rebuilds() const { return 0; }
  virtual std::uint64_t patch_softened() const { return 0; }
};

}  // namespace hapticloth::haptics
