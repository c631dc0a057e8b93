#include "haptics/modes/energy_bound.hpp"

#include <algorithm>

namespace hapticloth::haptics {

void EnergyBound::account(const std::array<Vec3, kMaxFingers>& x,
                          const std::array<Vec3, kMaxFingers>& sent,
                          const std::array<bool, kMaxFingers>& present, int fingers) noexcept {
  double into_model = 0.0;  // the hand's work on the model over the interval
  for (int f = 0; f < fingers; ++f) {
    if (present[f] && have_[f]) into_model -= sent[f].dot(x[f] - x_[f]);
    x_[f] = x[f];
    have_[f] = present[f];
  }
  reserve_ = touched_ ? reserve_ + into_model : 0.0;
  stats_.largest_reserve_j = std::max(stats_.largest_reserve_j, reserve_);
}

void EnergyBound::limit(std::array<Vec3, kMaxFingers>& force, const std::array<Vec3, kMaxFingers>& v,
                        const std::array<bool, kMaxFingers>& touching, int fingers) noexcept {
  touched_ = false;
  double giving = 0.0, taking = 0.0;  // the coming tick's work on the hand, J: > 0 and < 0 parts
  for (int f = 0; f < fingers; ++f) {
    if (!touching[f]) continue;
    touched_ = true;
    const double w = force[f].dot(v[f]) * period_;
    (w > 0.0 ? giving : taking) += w;
  }
  if (giving <= 0.0 || giving + taking <= reserve_) return;
  // Scale the giving fingers' work by beta so that beta giving + taking = reserve (beta >= 0).
  const double beta = std::clamp((reserve_ - taking) / giving, 0.0, 1.0);
  for (int f = 0; f < fingers; ++f) {
    if (!touching[f]) continue;
    const double v2 = v[f].squaredNorm(), along = force[f].dot(v[f]);
    if (!(along > 0.0) || !(v2 > 0.0)) continue;
    force[f] -= ((1.0 - beta) * along / v2) * v[f];
  }
  ++stats_.limited_ticks;
  stats_.withheld_j += (1.0 - beta) * giving;
}

}  // namespace hapticloth::haptics
