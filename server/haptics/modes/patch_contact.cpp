#include "haptics/modes/patch_contact.hpp"

#include <algorithm>
#include <cmath>

namespace hapticloth::haptics {

PatchContact::PatchContact(const std::vector<std::array<int, 3>>& tris,
                           const std::vector<Vec3>& rest, const std::vector<char>& pinned,
                           const PatchParams& p, int fingers, double radius, double k,
                           double damping, double friction)
    : tris_(tris), r_(radius), k_(k), b_(damping), mu_(friction) {
  for (int f = 0; f < fingers; ++f) patch_.push_back(std::make_unique<LocalPatch>(tris, rest, pinned, p));
}

// Separated: the patch still steps (it carries its own state between global steps).
void PatchContact::step_untouched(LocalPatch& patch, const ClothSnapshot& s, double now,
                                  const PatchTouch& t, Proxy& P) noexcept {
  PatchTouch free = t;
  free.contact = false;
  free.tri = -1;
  bool sl;
  patch.step(s, now, free, P.anchor, sl);
}

void PatchContact::touch(const ClothSnapshot& s, double now, double, const Fingertip& tip,
                         FingerReport& out) noexcept {
  const int f = tip.finger;
  const Vec3& c = tip.centre;
  Proxy& P = proxy_[f];
  out.position = c;
  out.proxy = c;
  out.force.setZero();
  out.in_contact = false;
  out.slipping = false;
  out.triangle = -1;
  out.stiffness = 0.0;
  if (s.time < 0.0 || !s.near[f]) return separate(P);
  LocalPatch& patch = *patch_[f];
  if (!patch.active() || (c - patch.centre()).norm() > 0.5 * patch.params_radius()) {
    patch.rebuild(s, f, c);
    ++rebuilds_;
    softened_ += patch.spring_scale() < 1.0;
  }
  const SurfacePoint sp = patch.closest(c);
  if (sp.triangle < 0) return separate(P);
  PatchTouch t;
  t.c = c;
  t.vc = tip.velocity;
  t.r = r_;
  t.k = k_;
  t.mu = mu_;
  for (int i = 0; i < 3; ++i) t.b[i] = sp.bary[i];
  const bool on = pressing(P, f, c, (c - sp.point).dot(sp.normal), std::sqrt(sp.dist2));
  t.side = P.side;
  if (!on) return step_untouched(patch, s, now, t, P);
  t.contact = true;
  t.tri = sp.triangle;
  render(patch, s, now, t, sp, P, out);
  out.impacts = impacts_[f];
}

void PatchContact::separate(Proxy& P) noexcept {
  P.contact = false;
  P.side = 0;
}

// Contact onset and end for a finger at c, h above the surface along its normal and dist from
// it: true while the sphere presses into the cloth from the side it came from.
bool PatchContact::pressing(Proxy& P, int finger, const Vec3& c, double h, double dist) noexcept {
  if (!P.contact) {
    // Separated: remember which side the finger is on; touching starts when the sphere reaches
    // the surface from that side.
    if (dist >= r_ || P.side == 0) {
      P.side = h >= 0.0 ? 1 : -1;
      if (dist >= r_) return false;
    }
    P.contact = true;
    P.anchor = c;
    ++impacts_[finger];  // contact onset: the simulation transfers the impact momentum (4.3.2)
  }
  const double depth = r_ - P.side * h;  // > 0: pressing into the cloth
  if (depth <= 0.0) {
    P.contact = false;  // left the surface on its own side
    return false;
  }
  return true;
}

// The patch resolves the contact within the tick (normal and friction springs on every
// substep); the user feels their mean, plus damping on the fingertip's own velocity.
void PatchContact::render(LocalPatch& patch, const ClothSnapshot& s, double now,
                          const PatchTouch& t, const SurfacePoint& sp, Proxy& P,
                          FingerReport& out) noexcept {
  const Vec3 ns = P.side * sp.normal;  // normal towards the finger
  bool slipping = false;
  const Vec3 Fu = patch.step(s, now, t, P.anchor, slipping);
  const double fnp = Fu.dot(ns);
  const double fn = std::max(0.0, fnp - b_ * t.vc.dot(ns));
  const Vec3 Ft = Fu - fnp * ns;
  out.slipping = slipping;
  out.force = fn * ns + Ft;
  out.spring = out.force;
  out.proxy = t.c + out.force / k_;
  out.normal = ns;
  out.contact = sp.point;
  const int bt = patch.global_triangle(sp.triangle);
  out.triangle = bt;
  // barycentric coordinates of the contact point in the global triangle
  const auto& g = tris_[bt];
  const ClosestPoint gp = closest_point_triangle(sp.point, s.x[g[0]], s.x[g[1]], s.x[g[2]]);
  for (int i = 0; i < 3; ++i) out.bary[i] = gp.b[i];
  out.stiffness = k_;
  out.in_contact = true;
  out.velocity = t.vc;
}

}  // namespace hapticloth::haptics
