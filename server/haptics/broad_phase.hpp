// Collision broad phase over the deforming cloth: an FCL bounding-volume hierarchy (k-DOP 18,
// refit bottom-up each simulation step; see notes on FCL's OBBRSS refit) queried with each
// fingertip's sphere grown by a margin that covers its motion until the next query.
#pragma once

#include <memory>
#include <vector>

#include <Eigen/Core>

namespace hapticloth::haptics {

class BroadPhase {
 public:
  BroadPhase(const std::vector<Eigen::Vector3d>& x, const std::vector<std::array<int, 3>>& tris);
  ~BroadPhase();
  /// Refit the hierarchy to new vertex positions (same count).
  void refit(const std::vector<Eigen::Vector3d>& x);
  /// Triangles whose bounding volumes overlap the sphere; at most `max_out`, sorted, unique.
  /// Returns the count written to `out`.
  int query_sphere(const Eigen::Vector3d& centre, double radius, int* out, int max_out);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hapticloth::haptics
