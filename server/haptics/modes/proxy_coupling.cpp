#include "haptics/modes/proxy_coupling.hpp"

#include <algorithm>

namespace hapticloth::haptics {

// The contact's parameters from the scene's fingertip: the sphere, its coupling to the device,
// Coulomb friction and the pressure law (the stiffening depth and sample spacing at theirs).
ContactParams contact_params(const FingerParams& f, double margin) {
  return {.radius = f.radius,
          .coupling_stiffness = f.stiffness,
          .coupling_damping = f.damping,
          .max_force = f.max_force,
          .friction = f.friction,
          .pressure_stiffness = f.contact_stiffness,
          .margin = margin};
}

ProxyCoupling::ProxyCoupling(const cloth::ClothModel& model, cloth::Integrator& integ, int fingers,
                             const FingerParams& finger, const CouplingParams& coupling, bool refine)
    : integ_(integ),
      fingers_(fingers),
      model_(model),
      finger_(finger),
      coupling_(coupling),
      tips_(model, model.triangles, fingers, contact_params(finger, coupling.margin), integ) {
  if (refine && mesh_needs_refinement(model, coupling.refinement, finger.radius))
    refine_ = std::make_unique<InlineRefinement>(make_refinement());
}

std::unique_ptr<LocalRefinement> ProxyCoupling::make_refinement() const {
  return std::make_unique<LocalRefinement>(model_, contact_params(finger_, coupling_.margin),
                                           integ_.config().gravity, coupling_.refinement);
}

// A fresh refinement on the worker (its children are built again at the next touch).
void ProxyCoupling::refine_beside_steps() {
  if (refine_) refine_ = std::make_unique<BackgroundRefinement>(make_refinement());
}

// The device's fingertips at the end of the coming step: the latest tick's positions carried
// forward at their velocity (the coupling then acts at the end of the step, implicitly).
std::array<FingerTarget, kMaxFingers> ProxyCoupling::targets(const HapticReport& r, double now) const {
  std::array<FingerTarget, kMaxFingers> t{};
  const double h = integ_.config().dt;
  const double ahead = std::clamp(now + h - r.time, 0.0, 2.0 * h);
  for (int f = 0; f < fingers_ && r.time >= 0.0; ++f) {
    t[f].valid = r.finger[f].present;
    t[f].position = r.finger[f].position + ahead * r.finger[f].velocity;
    t[f].velocity = r.finger[f].velocity;
  }
  return t;
}

void ProxyCoupling::couple(const HapticReport& r, double now, cloth::ClothState& s) {
  tips_.begin_step(s, targets(r, now), integ_.config().dt);
}

void ProxyCoupling::conclude(const cloth::ClothState& s) {
  tips_.end_step(s);
  if (refine_) refine_->after_step(s, tips_, fingers_);
}

void ProxyCoupling::fill(const HapticReport&, const cloth::ClothState&, ClothSnapshot& snap) {
  for (int f = 0; f < fingers_; ++f) snap.proxy[f] = tips_.result(f);
  snap.has_response = false;
}

// The multirate path's local model: the step's response to the fingertips (eq. 9 linearized),
// for the haptic loop to render from until the next step.
void ResponseCoupling::conclude(const cloth::ClothState& s) {
  ProxyCoupling::conclude(s);
  has_response_ = integ_.proxy_response(response_);
}

void ResponseCoupling::fill(const HapticReport& r, const cloth::ClothState& s, ClothSnapshot& snap) {
  ProxyCoupling::fill(r, s, snap);
  snap.has_response = has_response_;
  for (int p = 0; p < fingers_; ++p)
    for (int q = 0; q < fingers_; ++q)
      snap.response[p * kMaxFingers + q] = has_response_ ? response_[p * fingers_ + q] : cloth::Mat3::Zero();
}

}  // namespace hapticloth::haptics
