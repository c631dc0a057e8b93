#include "haptics/patch_contact.hpp"

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
void PatchContact::release(LocalPatch& patch, const ClothSnapshot& s, double now,
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
  const Vec3& vc = tip.velocity;
  Proxy& P = proxy_[f];
  out.position = c;
  out.proxy = c;
  out.force.setZero();
  out.in_contact = false;
  out.slipping = false;
  out.triangle = -1;
  out.stiffness = 0.0;
  if (s.time < 0.0 || !s.near[f]) {
    P.contact = false;
    P.side = 0;
    return;
  }
  LocalPatch& patch = *patch_[f];
  if (!patch.active() || (c - patch.centre()).norm() > 0.5 * patch.params_radius()) {
    patch.rebuild(s, c);
    ++rebuilds_;
    softened_ += patch.spring_scale() < 1.0;
  }
  const SurfacePoint sp = patch.closest(c);
  if (sp.triangle < 0) {
    P.contact = false;
    P.side = 0;
    return;
  }
  PatchTouch t;
  t.c = c;
  t.vc = vc;
  t.r = r_;
  t.k = k_;
  t.mu = mu_;
  for (int i = 0; i < 3; ++i) t.b[i] = sp.bary[i];
  const Vec3 n = sp.normal;
  const double h = (c - sp.point).dot(n);
  const double dist = std::sqrt(sp.dist2);
  if (!P.contact) {
    // Separated: remember which side the finger is on; touching starts when the sphere reaches
    // the surface from that side.
    if (dist >= r_ || P.side == 0) {
      P.side = h >= 0.0 ? 1 : -1;
      if (dist >= r_) {
        t.side = P.side;
        release(patch, s, now, t, P);
        return;
      }
    }
    P.contact = true;
    P.anchor = c;
    ++impacts_[f];  // contact onset: the simulation transfers the impact momentum (4.3.2)
  }
  t.side = P.side;
  const double depth = r_ - P.side * h;  // > 0: pressing into the cloth
  if (depth <= 0.0) {
    P.contact = false;  // left the surface on its own side
    release(patch, s, now, t, P);
    return;
  }
  const Vec3 ns = P.side * n;  // normal towards the finger
  // The patch resolves the contact within the tick (normal and friction springs on every
  // substep); the user feels their mean, plus damping on the fingertip's own velocity.
  t.contact = true;
  t.tri = sp.triangle;
  bool slipping = false;
  const Vec3 Fu = patch.step(s, now, t, P.anchor, slipping);
  const double fnp = Fu.dot(ns);
  const double fn = std::max(0.0, fnp - b_ * vc.dot(ns));
  const Vec3 Ft = Fu - fnp * ns;
  out.slipping = slipping;
  out.force = fn * ns + Ft;
  out.spring = out.force;
  out.proxy = c + out.force / k_;
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
  out.velocity = vc;
  out.impacts = impacts_[f];
}

}  // namespace hapticloth::haptics
