// Collision broad phase over the deforming cloth: an FCL bounding-volume hierarchy (AABB,
// refit bottom-up once a vertex has moved `refit_slack`; FCL's bottom-up refit is wrong for
// OBBRSS, right for AABB and k-DOP, and AABB's, with 6 bounds a node against 18, is the
// cheapest), walked with each fingertip's sphere grown by the displacement since the refit.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Core>

namespace hapticloth::haptics {

class BroadPhase {
 public:
  /// `refit_slack`: largest vertex displacement (m) before update() refits the hierarchy.
  BroadPhase(const std::vector<Eigen::Vector3d>& x, const std::vector<std::array<int, 3>>& tris,
             double refit_slack = 0.01);
  ~BroadPhase();
  /// Refit the hierarchy to new vertex positions (same count).
  void refit(const std::vector<Eigen::Vector3d>& x);
  /// Refit lazily: the hierarchy stays conservative if queries grow by the largest vertex
  /// displacement since the last refit; refit once that exceeds the slack.
  void update(const std::vector<Eigen::Vector3d>& x);
  /// Triangles whose bounding volumes overlap the sphere (grown by the displacement since the
  /// last refit); at most `max_out`, sorted, unique. Returns the count written to `out`.
  int query_sphere(const Eigen::Vector3d& centre, double radius, int* out, int max_out);
  /// Largest vertex displacement since the last refit, m (what queries grow by).
  double displacement() const { return disp_; }
  int triangles() const { return triangles_; }
  std::uint64_t refits() const { return refits_; }

 private:
  static constexpr int kMaxDepth = 256;  // query_sphere()'s walk: FCL's median split is balanced
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::vector<Eigen::Vector3d> x_refit_;  // positions at the last refit
  double slack_, disp_ = 0.0;
  int triangles_ = 0;
  std::uint64_t refits_ = 0;
};

}  // namespace hapticloth::haptics
