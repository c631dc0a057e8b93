#include "haptics/contact/geometry.hpp"

namespace hapticloth::haptics {

namespace {

// Ericson, Real-Time Collision Detection, 5.1.5: the point's Voronoi region of the triangle
// (vertex, edge or face) by the signs of a few dot products. The tests for the corners b and c,
// and for the edges ab and ac, are one test with b and c exchanged. For a corner q (r the other
// one), with own = (q - a).(p - q), other = (r - a).(p - q), from_a_q = (q - a).(p - a) and
// from_a_r = (r - a).(p - a):
//   p is in q's region when own >= 0 and other <= own;
//   area = from_a_q other - own from_a_r is r's barycentric weight of the face, unnormalised;
//   p is in edge aq's region when area <= 0, from_a_q >= 0 and own <= 0, at
//   t = from_a_q / (from_a_q - own) along it.
// (Each area is computed after its corner's test, as in the book: the compiler then fuses the
// same products, and the result is the same to the last bit.)
struct Corner {
  double own, other;
  bool in_corner() const { return own >= 0.0 && other <= own; }
  double area(double from_a_q, double from_a_r) const { return from_a_q * other - own * from_a_r; }
};

Corner corner(const Vec3& aq, const Vec3& ar, const Vec3& qp) { return {aq.dot(qp), ar.dot(qp)}; }

/// The parameter along edge aq where p projects, or -1 when p is not in the edge's region.
double on_edge_from_a(const Corner& q, double area, double from_a_q) {
  if (area <= 0.0 && from_a_q >= 0.0 && q.own <= 0.0) return from_a_q / (from_a_q - q.own);
  return -1.0;
}

}  // namespace

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
  const double from_a_b = ab.dot(ap), from_a_c = ac.dot(ap);
  if (from_a_b <= 0.0 && from_a_c <= 0.0) return set(1, 0, 0);
  const Corner kb = corner(ab, ac, p - b);
  if (kb.in_corner()) return set(0, 1, 0);
  const double vc = kb.area(from_a_b, from_a_c);
  if (const double v = on_edge_from_a(kb, vc, from_a_b); v >= 0.0) return set(1 - v, v, 0);
  const Corner kc = corner(ac, ab, p - c);
  if (kc.in_corner()) return set(0, 0, 1);
  const double vb = kc.area(from_a_c, from_a_b);
  if (const double w = on_edge_from_a(kc, vb, from_a_c); w >= 0.0) return set(1 - w, 0, w);
  // Edge bc: its region by a's weight, with the dot products from b and from c.
  const double va = kb.own * kc.own - kc.other * kb.other;
  const double along_b = kb.other - kb.own, along_c = kc.other - kc.own;
  if (va <= 0.0 && along_b >= 0.0 && along_c >= 0.0) {
    const double w = along_b / (along_b + along_c);
    return set(0, 1 - w, w);
  }
  const double denom = va + vb + vc;
  if (!(denom > 0.0)) return set(1, 0, 0);  // degenerate triangle
  const double v = vb / denom, w = vc / denom;
  return set(1 - v - w, v, w);
}

}  // namespace hapticloth::haptics
