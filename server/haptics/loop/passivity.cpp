#include "haptics/loop/passivity.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace hapticloth::haptics {

CouplingPassivity::CouplingPassivity(double stiffness, double max_force)
    : k_(stiffness), max_force_(max_force) {
  if (!(k_ > 0.0) || !(max_force_ > 0.0) || !std::isfinite(k_ + max_force_))
    throw std::invalid_argument("coupling passivity: stiffness and max force must be finite and > 0");
}

void CouplingPassivity::reset(int f) noexcept { fs_[f] = Finger{}; }

Vec3 CouplingPassivity::observe(int f, double dt, const Vec3& applied, const Vec3& x,
                                const Vec3& p, const Vec3& v, const Vec3& coupling,
                                const Vec3& spring, bool coupled) noexcept {
  Finger& s = fs_[f];
  const double stored = coupled ? 0.5 * spring.squaredNorm() / k_ : 0.0;
  if (!s.have) {  // the first tick: nothing flowed yet
    s = Finger{true, x, p, coupling, stored, 0.0};
    return Vec3::Zero();
  }
  // The energy the coupling absorbed over the interval (W_n in the header): the hand's side
  // with the force the hand got (the controller's damping included), the proxy's side with
  // the coupling's own force (the damping acts on the hand alone).
  const double absorbed = s.coupling.dot(p - s.p) - applied.dot(x - s.x) - (stored - s.stored);
  s.coupling = coupling;
  // Beyond the cap the reserve leaks away (time constant kReserveLeak): what the coupling
  // absorbed in the last tens of ms may pay for what it gives back now (a late tick's motion
  // enters in one interval and leaves over the catch-up), older dissipation may not.
  s.reserve += absorbed;
  if (s.reserve > kReserveCap) s.reserve = kReserveCap + (s.reserve - kReserveCap) * std::exp(-dt / kReserveLeak);
  s.x = x;
  s.p = p;
  s.stored = stored;
  stats_.deepest_deficit_j = std::max(stats_.deepest_deficit_j, -s.reserve);
  if (s.reserve >= -kDeadband) return Vec3::Zero();
  const double v2 = v.squaredNorm();
  if (v2 < 1e-12) return Vec3::Zero();  // no motion: a damper cannot dissipate now
  // alpha v with alpha = -R / (|v|^2 tau): the deficit is dissipated over kDissipationTime,
  // not in one tick, so the damping rises as gently as the coupling's own force does.
  Vec3 damp = v * (s.reserve / (v2 * kDissipationTime));
  const double n = damp.norm();
  if (n > max_force_) damp *= max_force_ / n;
  ++stats_.active_ticks;
  stats_.dissipated_j += damp.norm() * std::sqrt(v2) * dt;
  return damp;
}

}  // namespace hapticloth::haptics
