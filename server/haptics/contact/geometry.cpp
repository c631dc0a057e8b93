#include "haptics/contact/geometry.hpp"

namespace hapticloth::haptics {

// Ericson, Real-Time Collision Detection, 5.1.5: the point's Voronoi region of the triangle
// (vertex, edge or face) by the signs of a few dot products; the tests for c's region and edge
// ac's are b's and edge ab's with b and c, and so ab and ac, exchanged.
ClosestPoint closest_point_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  ClosestPoint r;
  auto set = [&](double u, double v, double w) {
    r.b[0] = u;
    r.b[1] = v;
    r.b[2] = w;
    r.point = u * a + v * b + w * c;
    r.dist2 = (p - r.point).squaredNorm();
    return r;
  };
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return set(1, 0, 0);
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return set(0, 1, 0);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    const double v = d1 / (d1 - d3);
    return set(1 - v, v, 0);
  }
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return set(0, 0, 1);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    const double w = d2 / (d2 - d6);
    return set(1 - w, 0, w);
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return set(0, 1 - w, w);
  }
  const double denom = va + vb + vc;
  if (!(denom > 0.0)) return set(1, 0, 0);  // degenerate triangle
  const double v = vb / denom, w = vc / denom;
  return set(1 - v - w, v, w);
}

}  // namespace hapticloth::haptics
