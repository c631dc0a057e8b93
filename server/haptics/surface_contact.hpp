// How a fingertip touches the cloth on the haptic thread: one interface, one implementation per
// surface model (ProxyContact: the proxies solved with the global cloth, direct coupling;
// PatchContact: the local refinement of section 4.2).
#pragma once

#include <array>

#include "haptics/handoff.hpp"

namespace hapticloth::haptics {

/// The local model of the multirate path (section 4.2: the global step is longer than the
/// haptic period). Response: the fingertip proxies are solved with the whole cloth at the
/// global step, which also hands over its linear response to the fingertips
/// (cloth::Integrator::proxy_response); the haptic loop renders from it between steps, both
/// fingers together. Patch: the paper's refined spring-mass patch per fingertip (4.2), with
/// the forces spread back on the global cloth by a kernel (4.3).
enum class LocalModel { Response, Patch };
inline const char* to_string(LocalModel m) { return m == LocalModel::Response ? "response" : "patch"; }

/// How the simulation and the haptic loop share the fingertips: Direct (the proxies solved with
/// the cloth at every haptic tick's step), or the multirate path with one of its local models.
enum class Rendering { Direct, Response, Patch };
inline Rendering rendering(bool local_patch, LocalModel m) {
  if (!local_patch) return Rendering::Direct;
  return m == LocalModel::Response ? Rendering::Response : Rendering::Patch;
}

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
};

}  // namespace hapticloth::haptics
