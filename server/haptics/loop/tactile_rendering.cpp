#include "haptics/loop/tactile_rendering.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace hapticloth::haptics {

namespace {

tactile::TactileParams channel_params(const devices::TactileCapability& cap, double tick_s) {
  tactile::TactileParams p;
  // A display with pins only still has its skin tracked: one sample a tick, not sent.
  p.rate = cap.vibration() ? cap.vibration_rate : static_cast<int>(std::lround(1.0 / tick_s));
  p.pin_rows = cap.pin_rows;
  p.pin_cols = cap.pin_cols;
  p.pin_pitch = cap.pin_pitch;
  return p;
}

}  // namespace

TactileRendering::TactileRendering(const cloth::ClothModel& model, const devices::TactileCapability& cap,
                                   int fingers, double tick_s, double finger_radius)
    : model_(model), cap_(cap), fingers_(fingers), radius_(finger_radius) {
  if (!model.material.surface.present())
    throw std::invalid_argument("tactile: the material has no [surface] (docs/materials.md)");
  if (!cap.any()) throw std::invalid_argument("tactile: the device declares no tactile display");
  for (int f = 0; f < fingers_; ++f)
    channel_[f] = std::make_unique<tactile::TactileChannel>(model.material.surface, channel_params(cap, tick_s), tick_s);
}

// The step's contact as the tracker takes it: the proxy's own (direct coupling and the response
// model), or, for a contact model that reports only a triangle of the global mesh (the patch),
// that triangle at the step.
tactile::WeaveAnchor TactileRendering::anchor(const ClothSnapshot& s, const FingerReport& r, int f) const noexcept {
  tactile::WeaveAnchor a;
  a.time = s.time;
  const ProxyResult& p = s.proxy[f];
  if (p.valid && p.in_contact && !p.weave_map.isZero(0.0)) {
    a.valid = true;
    a.uv = {p.weave_u, p.weave_v};
    a.map = p.weave_map;
    a.surface_velocity = p.surface_velocity;
    return a;
  }
  const int t = r.triangle;
  if (t < 0 || t >= static_cast<int>(model_.weave_uv.size()) || s.x.empty()) return a;
  const auto& tri = model_.triangles[t];
  const auto& uv = model_.weave_uv[t];
  auto corner = [&](int k) { return Eigen::Vector2d(uv[k][0], uv[k][1]); };
  a.valid = true;
  a.uv = r.bary[0] * corner(0) + r.bary[1] * corner(1) + r.bary[2] * corner(2);
  a.map = tactile::weave_map(s.x[tri[0]], s.x[tri[1]], s.x[tri[2]], corner(0), corner(1), corner(2));
  a.surface_velocity = r.bary[0] * s.v[tri[0]] + r.bary[1] * s.v[tri[1]] + r.bary[2] * s.v[tri[2]];
  return a;
}

// The finger pad's velocity, m/s: the proxy's (the fingertip's surface where it meets the cloth),
// not the device's. Where friction holds the pad to the cloth the proxy moves with the cloth
// while the device stretches the coupling spring; the pad does not slide over the fabric.
Vec3 TactileRendering::pad_velocity(const FingerReport& r, int f, double dt) const noexcept {
  if (!had_contact_[f] || !(dt > 0.0)) return r.velocity;
  return (r.proxy - last_proxy_[f]) / dt;
}

void TactileRendering::render(const ClothSnapshot& s, const HapticReport& rep, double now, double dt,
                              devices::TactileCommand& out) noexcept {
  ++c_.frames;
  for (int f = 0; f < fingers_; ++f) {
    const FingerReport& r = rep.finger[f];
    tactile::TactileInput in;
    TactilePlace& place = place_[f];
    place = TactilePlace{};
    if (r.present && r.in_contact) {
      const tactile::WeaveAnchor a = anchor(s, r, f);
      if (a.valid) {
        const Eigen::Vector2d uv = tracker_[f].track(a, pad_velocity(r, f, dt), now, dt);
        in.in_contact = true;
        // The normal force the user feels (towards the finger), and the contact patch: the
        // step's (direct coupling, the response model), or for a contact model without one the
        // patch a sphere of radius R pressed delta into the cloth makes, sqrt(2 R delta).
        in.normal_force = std::max(0.0, r.force.dot(r.normal));
        in.u = uv.x();
        in.v = uv.y();
        const ProxyResult& p = s.proxy[f];
        in.patch_radius = p.valid && p.patch_radius > 0.0 ? p.patch_radius
                                                          : std::sqrt(2.0 * radius_ * std::max(0.0, p.penetration));
        place = TactilePlace{true, in.u, in.v, in.normal_force};
      }
    }
    if (!in.in_contact) tracker_[f].reset();
    last_proxy_[f] = r.proxy;
    had_contact_[f] = in.in_contact;
    channel_[f]->tick(in, scratch_);
    devices::TactileFrame& frame = out.finger[f];
    frame = scratch_;
    if (!cap_.vibration()) frame.samples = 0;
    const auto v = frame.vibration.begin();
    if (std::any_of(v, v + frame.samples, [](float x) { return x != 0.0f; })) ++c_.textured_ticks;
    if (scratch_.slipping) ++c_.slip_ticks;
  }
  for (int f = fingers_; f < kMaxFingers; ++f) out.finger[f] = devices::TactileFrame{};
}

}  // namespace hapticloth::haptics
