#include "haptics/modes/response_contact.hpp"

#include <algorithm>
#include <cmath>

namespace hapticloth::haptics {

// Finger p's force from the step's response to every present fingertip's motion.
Vec3 ResponseContact::follow(const ClothSnapshot& s, const std::array<Fingertip, kMaxFingers>& tips,
                             const std::array<bool, kMaxFingers>& present, int fingers,
                             int p) const noexcept {
  Vec3 F = s.proxy[p].force;
  for (int q = 0; q < fingers; ++q) {
    const ProxyResult& rq = s.proxy[q];
    if (!present[q] || !rq.valid) continue;
    // The spring the step solved with: with local refinement the scene's in series with the
    // compliance the global mesh lacks, so the force follows the refined cloth's stiffness.
    const double k = rq.coupling_stiffness > 0.0 ? rq.coupling_stiffness : k_;
    const Vec3 pull = k * (tips[q].centre - rq.target) + c_ * (tips[q].velocity - rq.target_velocity);
    const Eigen::Matrix3d& R = s.response[p * kMaxFingers + q];
    F += R * pull - (p == q ? pull : Vec3::Zero());
  }
  return F;
}

// Contact is one-sided: a finger whose force would pull it towards the cloth has left it (no
// force); the tangential part stays within mu x the normal part (the step's contacts slide
// beyond that).
Vec3 ResponseContact::one_sided(const ProxyResult& r, const Vec3& F, bool& contact) const noexcept {
  contact = false;
  if (!r.in_contact || !F.allFinite()) return Vec3::Zero();
  const double fn = F.dot(r.normal);
  if (!(fn > 0.0)) return Vec3::Zero();
  contact = true;
  const Vec3 ft = F - fn * r.normal;
  const double ftn = ft.norm(), lim = mu_ * fn;
  return ftn > lim ? Vec3(fn * r.normal + ft * (lim / ftn)) : F;
}

void ResponseContact::prepare(const ClothSnapshot& s, const std::array<Fingertip, kMaxFingers>& tips,
                              const std::array<bool, kMaxFingers>& present, int fingers) noexcept {
  new_step_ = s.time >= 0.0 && s.step != step_;
  if (new_step_) {
    fade_ = step_time_ >= 0.0 ? s.time - step_time_ : 0.0;
    step_ = s.step;
    step_time_ = s.time;
  }
  for (int p = 0; p < fingers; ++p) {
    const ProxyResult& r = s.proxy[p];
    if (s.time < 0.0 || !r.valid || !present[p]) {
      force_[p].setZero();
      contact_[p] = false;
      continue;
    }
    const Vec3 F = s.has_response ? follow(s, tips, present, fingers, p) : r.force;
    force_[p] = one_sided(r, F, contact_[p]);
  }
}

// The model's force, with what a new step changed faded in over the step's interval.
Vec3 ResponseContact::faded(int f, double now) noexcept {
  if (new_step_) {
    offset_[f] = last_contact_[f] && contact_[f] ? Vec3(last_[f] - force_[f]) : Vec3::Zero();
    fade_start_ = now;
  }
  const double w = fade_ > 0.0 ? std::max(0.0, 1.0 - (now - fade_start_) / fade_) : 0.0;
  const Vec3 F = contact_[f] ? Vec3(force_[f] + w * offset_[f]) : Vec3::Zero();
  last_[f] = F;
  last_contact_[f] = contact_[f];
  return F;
}

void ResponseContact::release(int finger) noexcept {
  last_contact_[finger] = false;
  offset_[finger].setZero();
}

void ResponseContact::touch(const ClothSnapshot& s, double now, double, const Fingertip& tip,
                            FingerReport& out) noexcept {
  const int f = tip.finger;
  const ProxyResult& r = s.proxy[f];
  const Vec3 F = faded(f, now);
  out.position = tip.centre;
  out.velocity = tip.velocity;
  out.force = F;
  out.spring = F;
  out.proxy = tip.centre + F / k_;  // where the coupling spring's stretch puts it
  report_proxy_contact(r, contact_[f], k_, out);
}

}  // namespace hapticloth::haptics
