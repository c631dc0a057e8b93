#include "tactile/weave_tracker.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

namespace hapticloth::tactile {

WeaveMap weave_map(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Eigen::Vector2d& uv0,
                   const Eigen::Vector2d& uv1, const Eigen::Vector2d& uv2) {
  Eigen::Matrix<double, 3, 2> E;
  E << x1 - x0, x2 - x0;
  Eigen::Matrix2d W;
  W << uv1 - uv0, uv2 - uv0;
  const Eigen::Matrix2d G = E.transpose() * E;
  const double det = G.determinant();
  // det G = |e1|^2 |e2|^2 sin^2(angle): a sliver under 1e-6 rad maps to nothing.
  if (!(std::abs(det) > 1e-12 * (G.trace() * G.trace()) && std::isfinite(det))) return WeaveMap::Zero();
  return W * G.inverse() * E.transpose();
}

Eigen::Vector2d WeaveTracker::track(const WeaveAnchor& a, const Vec3& tip_velocity, double now,
                                    double dt) noexcept {
  if (!a.valid) {
    tracking_ = false;
    return uv_;
  }
  const Eigen::Vector2d raw = a.map * (tip_velocity - a.surface_velocity);  // m/s over the fabric
  if (!tracking_) {
    tracking_ = true;
    uv_ = a.uv;
    slip_ = raw;
    return uv_;
  }
  slip_ += dt / (kSlipSmoothing + dt) * (raw - slip_);
  const Eigen::Vector2d& slip = slip_;
  if (slip.norm() < kStillSpeed) return uv_;  // not slipping: the skin stays where it is
  const Eigen::Vector2d step = slip * dt;
  uv_ += step;
  const Eigen::Vector2d anchor_now = a.uv + slip * std::max(0.0, now - a.time);
  Eigen::Vector2d pull = std::min(1.0, dt / tau_) * (anchor_now - uv_);
  const double most = kMaxPull * step.norm();  // the speed over the fabric changes by kMaxPull at most
  if (pull.norm() > most) pull *= most / pull.norm();
  uv_ += pull;
  return uv_;
}

}  // namespace hapticloth::tactile
