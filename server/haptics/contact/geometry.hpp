// Exact sphere-triangle narrow phase (section 3.4): closest point of a triangle to a point,
// with barycentric coordinates, and vertex normals for force shading (4.1.2).
#pragma once

#include <Eigen/Core>

namespace hapticloth::haptics {

using Vec3 = Eigen::Vector3d;

struct ClosestPoint {
  Vec3 point;
  double b[3];   ///< barycentric coordinates of `point` (sum 1, each >= 0)
  double dist2;  ///< squared distance to the query
};

/// Closest point of triangle (a, b, c) to p (Ericson, Real-Time Collision Detection 5.1.5).
ClosestPoint closest_point_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

}  // namespace hapticloth::haptics
