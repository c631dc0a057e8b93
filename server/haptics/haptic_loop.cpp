#include "haptics/haptic_loop.hpp"

#include <algorithm>
#include <cmath>

#include "haptics/geometry.hpp"

namespace hapticloth::haptics {

HapticLoop::HapticLoop(const std::vector<std::array<int, 3>>& triangles, int vertices,
                       devices::DeviceHandle& device, devices::SafetyGate& gate,
                       const FingerParams& finger, const DeviceMapping& map,
                       TripleBuffer<ClothSnapshot>& from_sim, TripleBuffer<HapticReport>& to_sim)
    : tris_(triangles),
      dev_(device),
      gate_(gate),
      fp_(finger),
      map_(map),
      in_(from_sim),
      out_(to_sim),
      fingers_(device.info().fingers) {
  (void)vertices;
  k_ = std::min(fp_.stiffness, device.info().max_stiffness);
}

void HapticLoop::finger_contact(int f, double now, double tick_dt, const Vec3& c,
                                const Vec3& vc, FingerReport& out) noexcept {
  const ClothSnapshot& s = in_.front();
  Proxy& P = proxy_[f];
  out.position = c;
  out.proxy = c;
  out.force.setZero();
  out.in_contact = false;
  out.slipping = false;
  out.triangle = -1;
  out.stiffness = 0.0;
  const int nc = s.time >= 0.0 ? s.ncand[f] : 0;
  if (nc == 0) {
    P.contact = false;
    P.side = 0;
    return;
  }
  // The surface under the finger: the local patch (4.2), or the global cloth with an exact
  // narrow phase on the candidates, extrapolated at constant velocity since its last step.
  LocalPatch* patch = patch_.empty() ? nullptr : patch_[f].get();
  int bt = -1, refined = -1;
  double bary[3] = {1, 0, 0};
  Vec3 q, n, vs;
  double best = 1e300;
  if (patch) {
    if (!patch->active() || (c - patch->centre()).norm() > 0.5 * patch->params_radius()) {
      patch->rebuild(s, c);
      ++rebuilds_;
      softened_ += patch->spring_scale() < 1.0;
    }
    const SurfacePoint sp = patch->closest(c);
    if (sp.triangle < 0) {
      P.contact = false;
      P.side = 0;
      return;
    }
    best = sp.dist2;
    q = sp.point;
    n = sp.normal;
    vs = sp.velocity;
    refined = sp.triangle;
    for (int i = 0; i < 3; ++i) bary[i] = sp.bary[i];
    bt = patch->global_triangle(refined);
  } else {
    const double dt = extrapolate_ ? std::clamp(now - s.time, 0.0, 0.05) : 0.0;
    ClosestPoint bc{};
    bc.point.setZero();
    for (int k = 0; k < nc; ++k) {
      const auto& t = tris_[s.cand[f][k]];
      const Vec3 a = s.x[t[0]] + dt * s.v[t[0]];
      const Vec3 b = s.x[t[1]] + dt * s.v[t[1]];
      const Vec3 cc = s.x[t[2]] + dt * s.v[t[2]];
      const ClosestPoint cp = closest_point_triangle(c, a, b, cc);
      if (cp.dist2 < best) {
        best = cp.dist2;
        bt = s.cand[f][k];
        bc = cp;
      }
    }
    const auto& t = tris_[bt];
    // Force shading (4.1.2): the normal interpolated from vertex normals at the contact point,
    // so the force direction turns smoothly across triangle edges.
    n = bc.b[0] * s.n[t[0]] + bc.b[1] * s.n[t[1]] + bc.b[2] * s.n[t[2]];
    const double nn = n.norm();
    n = nn > 0.0 ? Vec3(n / nn) : Vec3::UnitZ();
    vs = bc.b[0] * s.v[t[0]] + bc.b[1] * s.v[t[1]] + bc.b[2] * s.v[t[2]];
    q = bc.point;
    for (int i = 0; i < 3; ++i) bary[i] = bc.b[i];
  }
  const double h = (c - q).dot(n);
  const double dist = std::sqrt(best);
  if (!P.contact) {
    // Separated: remember which side the finger is on; touching starts when the sphere reaches
    // the surface from that side.
    if (dist >= fp_.radius || P.side == 0) {
      P.side = h >= 0.0 ? 1 : -1;
      if (dist >= fp_.radius) {
        if (patch) {
          bool sl;
          patch->step(s, now, false, c, vc, fp_.radius, k_, fp_.friction, P.side, -1, bary, P.anchor, sl);
        }
        return;
      }
    }
    P.contact = true;
    P.anchor = c;
    ++impacts_[f];  // contact onset: the simulation transfers the impact momentum (4.3.2)
  }
  const double depth = fp_.radius - P.side * h;  // > 0: pressing into the cloth
  if (depth <= 0.0) {
    P.contact = false;  // left the surface on its own side
    if (patch) {
      bool sl;
      patch->step(s, now, false, c, vc, fp_.radius, k_, fp_.friction, P.side, -1, bary, P.anchor, sl);
    }
    return;
  }
  const Vec3 ns = P.side * n;  // normal towards the finger
  // God-object: the proxy rests on the surface on the finger's side; the user feels the spring
  // from the fingertip to it, plus normal damping relative to the cloth.
  // Normal damping on the fingertip's own velocity (virtual-coupling damping for the device).
  // Damping against the cloth's velocity would feed the cloth's motion back through the
  // one-step-late handoff and set up a two-tick oscillation of the light cloth vertices.
  double fn = std::max(0.0, k_ * depth - fp_.damping * vc.dot(ns));
  Vec3 Ft = Vec3::Zero();
  if (patch) {
    // The patch resolves the contact within the tick (normal and friction springs on every
    // substep); the user feels their mean, plus the damping on the fingertip's velocity.
    bool slipping = false;
    const Vec3 Fu = patch->step(s, now, true, c, vc, fp_.radius, k_, fp_.friction, P.side, refined,
                                bary, P.anchor, slipping);
    const double fnp = Fu.dot(ns);
    fn = std::max(0.0, fnp - fp_.damping * vc.dot(ns));
    Ft = Fu - fnp * ns;
    out.slipping = slipping;
  } else {
    // Coulomb friction, god-object style: the anchor is where the fingertip centre touched
    // down, carried by the cloth. While the fingertip stays within the friction cone around it
    // the tangential spring sticks; beyond, the anchor slides along behind the finger (slip).
    // (Anchoring the closest point instead would jump when the finger sits in a dimple, whose
    // closest point is not unique.)
    P.anchor += tick_dt * vs;
    Vec3 d = P.anchor - c;
    d -= d.dot(ns) * ns;
    Ft = k_ * d;
    const double ft = Ft.norm(), lim = fp_.friction * fn;
    if (ft > lim) {
      Ft *= lim / ft;
      out.slipping = true;
    }
    P.anchor = c + Ft / k_;
  }
  out.force = fn * ns + Ft;
  out.proxy = c + out.force / k_;
  out.normal = ns;
  out.contact = q;
  out.triangle = bt;
  if (patch) {  // barycentric coordinates of the contact point in the global triangle
    const auto& g = tris_[bt];
    const ClosestPoint gp = closest_point_triangle(q, s.x[g[0]], s.x[g[1]], s.x[g[2]]);
    for (int i = 0; i < 3; ++i) bary[i] = gp.b[i];
  }
  for (int i = 0; i < 3; ++i) out.bary[i] = bary[i];
  out.stiffness = k_;
  out.in_contact = true;
  out.velocity = vc;
  out.impacts = impacts_[f];
}

void HapticLoop::enable_local_patch(const std::vector<Vec3>& rest, const std::vector<char>& pinned,
                                    const PatchParams& p) {
  patch_.clear();
  for (int f = 0; f < fingers_; ++f) patch_.push_back(std::make_unique<LocalPatch>(tris_, rest, pinned, p));
}

void HapticLoop::tick(double now) noexcept {
  ++tick_;
  const double tick_dt = last_now_ >= 0.0 ? std::clamp(now - last_now_, 0.0, 0.05) : 0.0;
  if (dev_.read(now, state_) == devices::Status::Error) ++device_errors_;
  in_.acquire();
  const ClothSnapshot& s = in_.front();
  bool any_cand = false;
  for (int f = 0; f < fingers_; ++f) {
    any_cand = any_cand || (s.time >= 0.0 && s.ncand[f] > 0);
    if (s.overflow[f]) ++overflows_;
  }
  if (!any_cand) ++np_skipped_;
  bool contact = false;
  report_.time = now;
  report_.tick = tick_;
  for (int f = 0; f < fingers_; ++f) {
    const Vec3 c = map_.origin + map_.R * state_.finger[f].position;
    const Vec3 vc = map_.R * state_.finger[f].velocity;
    finger_contact(f, now, tick_dt, c, vc, report_.finger[f]);
    contact = contact || report_.finger[f].in_contact;
    // Scene -> device frame for the force.
    cmd_.force[f] = map_.R.transpose() * report_.finger[f].force;
  }
  if (contact) ++contact_ticks_;
  gate_.apply(now, state_.received_time, cmd_, gated_);
  if (dev_.write(now, gated_) == devices::Status::Error) ++device_errors_;
  // The simulation gets what the user actually feels (after the gate), in the scene frame.
  for (int f = 0; f < fingers_; ++f) {
    FingerReport& r = report_.finger[f];
    if (r.in_contact) r.force = map_.R * gated_.force[f];
  }
  out_.back() = report_;
  out_.publish();
  last_now_ = now;
}

}  // namespace hapticloth::haptics
