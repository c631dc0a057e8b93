// Where on the fabric a fingertip is, tick by tick, in the cloth's material coordinates (u along
// the weft, v along the warp, m): what the tactile channel reads the surface at.
//
// The global step gives an anchor: the material point the contact normal through the proxy
// meets, the cloth's velocity there, and the map from a displacement on the cloth's surface to
// a displacement in material coordinates. The anchor alone wobbles from step to step: the
// contact's summed normal turns as samples join and leave the patch, so the ray's hit moves by
// up to a few hundred micrometres a tick, against a weave period of a few hundred. So the
// tracker integrates the fingertip's slip over the cloth instead,
//   d(u, v)/dt = M (v_tip - v_cloth),                                   (slip in material coordinates)
// and pulls the result towards the anchor (advanced by the same slip to the tick's time) with a
// time constant tau, 1 s: slow enough to average out the anchor's wobble over an element (the
// anchor's speed swings as the ray crosses the dimple's facets, while the slip's is steady:
// docs/tactile.md, 'One fingertip, one tick'), fast enough that the integration's drift (M and
// the cloth's velocity held between steps) stays bounded. The pull
// is at most kMaxPull of the tick's slip, so that an anchor's jump changes the frequency the
// weave is felt at by no more than that, rather than as a burst. A fingertip
// that does not slip over the cloth does not move over its surface: a stroke that drags the
// cloth with it feels no texture, and a still fingertip stays exactly where it is (a slip under
// kStillSpeed is none, and the pull is applied only while slipping).
#pragma once

#include <Eigen/Core>

namespace hapticloth::tactile {

using Vec3 = Eigen::Vector3d;
using WeaveMap = Eigen::Matrix<double, 2, 3>;

/// d(u, v)/dx on the triangle (x0, x1, x2) whose corners sit at material points uv0, uv1, uv2:
/// M = W (E^T E)^-1 E^T, with E = [x1 - x0, x2 - x0] and W = [uv1 - uv0, uv2 - uv0]. It maps a
/// displacement in the triangle's plane to the material displacement, and the normal to zero.
/// Zero for a degenerate triangle.
WeaveMap weave_map(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Eigen::Vector2d& uv0,
                   const Eigen::Vector2d& uv1, const Eigen::Vector2d& uv2);

/// A global step's contact, as the tracker takes it.
struct WeaveAnchor {
  bool valid = false;
  double time = 0.0;                ///< loop clock of the step, s
  Eigen::Vector2d uv = Eigen::Vector2d::Zero();  ///< material coordinates of the contact, m
  WeaveMap map = WeaveMap::Zero();  ///< d(u, v)/dx there
  Vec3 surface_velocity = Vec3::Zero();  ///< the cloth's velocity there, m/s
};

class WeaveTracker {
 public:
  /// `tau`: s, the time constant of the pull towards the anchor.
  explicit WeaveTracker(double tau = 1.0) : tau_(tau) {}
  static constexpr double kMaxPull = 0.05;
  /// m/s: a slip slower than this is no slip. A fingertip held still on a cloth still settling
  /// creeps over it by micrometres a second; the finest shipped weave (0.4 mm) crossed at 1 mm/s
  /// gives 2.5 Hz, far under the display's band (20-400 Hz), so nothing felt is lost.
  static constexpr double kStillSpeed = 1e-3;
  /// s: the slip's first-order smoothing. The cloth's velocity at the contact carries the
  /// simulation's tick-to-tick noise (a pinched cloth's contact solve); unsmoothed, a hand
  /// carrying the cloth felt it as a buzz of a few micrometres.
  static constexpr double kSlipSmoothing = 0.005;

  /// Lost contact: the next track() starts at its anchor.
  void reset() { tracking_ = false; }
  /// The fingertip's material coordinates at loop time `now`, `dt` after the last call, moving
  /// at `tip_velocity` (m/s, scene frame).
  Eigen::Vector2d track(const WeaveAnchor& a, const Vec3& tip_velocity, double now, double dt) noexcept;
  bool tracking() const { return tracking_; }

 private:
  double tau_;
  bool tracking_ = false;
  Eigen::Vector2d uv_ = Eigen::Vector2d::Zero();
  Eigen::Vector2d slip_ = Eigen::Vector2d::Zero();  // m/s, smoothed
};

}  // namespace hapticloth::tactile
