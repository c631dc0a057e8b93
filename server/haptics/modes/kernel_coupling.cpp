#include "haptics/modes/kernel_coupling.hpp"

#include <algorithm>

namespace hapticloth::haptics {

KernelCoupling::KernelCoupling(const cloth::ClothModel& model, cloth::Integrator& integ, int fingers,
                               double radius, double finger_mass, double patch_radius, double margin)
    : model_(model),
      integ_(integ),
      tris_(model.triangles),
      fingers_(fingers),
      R_(radius),
      finger_mass_(finger_mass),
      patch_radius_(patch_radius),
      margin_(margin) {
  w_.assign(model_.num_vertices(), 0.0);
}

void KernelCoupling::fill(const HapticReport& r, const cloth::ClothState& s, ClothSnapshot& snap) {
  for (int f = 0; f < fingers_; ++f) snap.proxy[f] = ProxyResult{};
  snap.has_response = false;
  list_patch_candidates(r, s, snap);
}

// The patch model's candidates per finger: the global triangles with a corner within the patch
// radius of anywhere the fingertip can be before the next snapshot (its travel at its present
// speed over two steps, plus the contact margin), in index order, up to the snapshot's room
// (the rest counted). One pass over the triangles here, on the simulation thread.
void KernelCoupling::list_patch_candidates(const HapticReport& r, const cloth::ClothState& s,
                                           ClothSnapshot& snap) {
  const double dt = integ_.config().dt;
  for (int f = 0; f < fingers_; ++f) {
    std::vector<int>& out = snap.near_triangles[f];
    const int room = static_cast<int>(out.size());
    int n = 0;
    if (snap.near[f]) {
      const Vec3& c = r.finger[f].position;
      const double reach = patch_radius_ + 2.0 * dt * r.finger[f].velocity.norm() + margin_;
      const double reach2 = reach * reach;
      bool overflow = false;
      for (int t = 0; t < static_cast<int>(tris_.size()); ++t) {
        const auto& g = tris_[t];
        bool in = false;
        for (int k = 0; k < 3; ++k) in = in || (s.x[g[k]] - c).squaredNorm() < reach2;
        if (!in) continue;
        if (n < room) out[n++] = t;
        else overflow = true;
      }
      overflows_ += overflow;
    }
    snap.near_count[f] = n;
  }
}

double KernelCoupling::apply_impact(const FingerReport& c, double me, cloth::ClothState& s) {
  const double R2 = R_ * R_;
  const Vec3& n = c.normal;
  double ms = 0.0, ps = 0.0;
  for (int i = 0; i < model_.num_vertices(); ++i) {
    w_[i] = 0.0;
    if (model_.pinned[i]) continue;
    const double d2 = (s.x[i] - c.contact).squaredNorm();
    if (d2 >= R2) continue;
    const double u = 1.0 - d2 / R2;
    w_[i] = u * u;  // phi_i, 1 at the contact point
    ms += model_.mass[i] * w_[i];
    ps += model_.mass[i] * w_[i] * s.v[i].dot(n);
  }
  if (ms <= 0.0 || me <= 0.0) return 0.0;
  const double vs = ps / ms, ve = c.velocity.dot(n);
  const double ves = (me * ve + ms * vs) / (me + ms);
  for (int i = 0; i < model_.num_vertices(); ++i)
    if (w_[i] > 0.0) s.v[i] += w_[i] * (ves - vs) * n;
  return ms * (ves - vs);
}

void KernelCoupling::apply(const HapticReport& r, cloth::ClothState& s, cloth::Integrator& integ) {
  for (int fi = 0; fi < fingers_; ++fi) {
    const FingerReport& c = r.finger[fi];
    if (r.time < 0.0 || !c.in_contact || c.impacts == impacts_seen_[fi]) continue;
    impacts_seen_[fi] = c.impacts;
    apply_impact(c, finger_mass_, s);
  }
  auto& f = integ.external_forces();
  auto& K = integ.external_stiffness();
  bool any = false;
  for (int fi = 0; fi < fingers_; ++fi) any = any || (r.time >= 0.0 && r.finger[fi].in_contact);
  if (!any && !integ.external_stiffness_on) return;
  std::fill(f.begin(), f.end(), Vec3::Zero());
  std::fill(K.begin(), K.end(), cloth::Mat3::Zero());
  integ.external_stiffness_on = any;
  if (!any) return;
  const double R2 = R_ * R_;
  for (int fi = 0; fi < fingers_; ++fi) {
    const FingerReport& c = r.finger[fi];
    if (!c.in_contact) continue;
    // Kernel weights around the contact point (4.3): w ~ A_i (1 - d^2/R^2)^2, normalized.
    double sum = 0.0;
    for (int i = 0; i < model_.num_vertices(); ++i) {
      const double d2 = (s.x[i] - c.contact).squaredNorm();
      w_[i] = 0.0;
      if (d2 >= R2 || model_.pinned[i]) continue;
      const double u = 1.0 - d2 / R2;
      w_[i] = model_.vertex_area[i] * u * u;
      sum += w_[i];
    }
    const Vec3 F = -c.force;  // the cloth gets the reaction of what the user feels
    // Contact stiffness seen by the cloth: the normal spring, and while the friction sticks the
    // tangential spring too (the anchor holds the cloth in every direction). Entering the
    // implicit solve, it keeps the light vertices under the finger stable.
    const cloth::Mat3 nn = c.slipping ? cloth::Mat3(c.stiffness * c.normal * c.normal.transpose())
                                      : cloth::Mat3(c.stiffness * cloth::Mat3::Identity());
    if (sum <= 0.0) {  // kernel found no free vertex: the contact triangle's own corners
      const auto& t = tris_[c.triangle];
      for (int k = 0; k < 3; ++k) {
        f[t[k]] += c.bary[k] * F;
        K[t[k]] += c.bary[k] * nn;
      }
      continue;
    }
    for (int i = 0; i < model_.num_vertices(); ++i) {
      if (w_[i] == 0.0) continue;
      const double wi = w_[i] / sum;
      f[i] += wi * F;
      K[i] += wi * nn;  // row-sum lumped contact stiffness: the spring acts implicitly
    }
  }
}

}  // namespace hapticloth::haptics
