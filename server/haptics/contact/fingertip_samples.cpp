// Where the fingertip meets the cloth (fingertip_contact.hpp): the sample points of the
// candidate triangles near the sphere, and their place on it.
#include "haptics/contact/fingertip_contact.hpp"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cmath>
#include <iterator>
#include <limits>
#include <stdexcept>
#include <string>

#include <Eigen/Geometry>

#include "hal/device.hpp"
#include "haptics/contact/geometry.hpp"
#include "tactile/weave_tracker.hpp"

namespace hapticloth::haptics {

namespace {
// A point deeper than this inside a sphere is added as a contact.
constexpr double kAddDepth = 5e-6;  // m
}  // namespace

// The samples of triangle t (positions x) that can lie within R of c, in ascending order, with
// their share of the triangle's area. The samples are the nodes of an m x m subdivision (the
// trapezoidal rule on each sub-triangle: a node carries a third of the area of every
// sub-triangle it is a corner of): node (i, j), i + j <= m, is at b1 = i / m, b2 = j / m,
// numbered row by row. So the cloth's vertices and points along its edges are samples
// themselves: a vertex tented into a sphere or a fold's ridge is pushed out directly (with
// sub-triangle centroids as samples, such a vertex stood up to a third of the spacing deeper
// than its nearest sample). The sphere's reach projected on the triangle's plane is an ellipse in barycentric
// coordinates (b - b*)^T G (b - b*) <= R^2 - h^2 (G the Gram matrix of the edges, b* the foot
// of c, h its height); its bounding box picks the rows and columns of the node grid.
// A triangle the size of the fingertip or smaller is enumerated whole.
template <class Fn>
void FingertipContact::for_samples_near(int t, const std::vector<Vec3>& x, const Vec3& c,
                                        double R, Fn&& fn) const {
  const int m = sub_[t];
  const auto& tr = tris_[t];
  const Vec3 e1 = x[tr[1]] - x[tr[0]], e2 = x[tr[2]] - x[tr[0]], d = c - x[tr[0]];
  const double g11 = e1.dot(e1), g12 = e1.dot(e2), g22 = e2.dot(e2);
  const double det = g11 * g22 - g12 * g12;
  double lo1 = 0.0, hi1 = 1.0, lo2 = 0.0, hi2 = 1.0;
  if (m > 1 && det > 1e-30) {
    const double r1 = e1.dot(d), r2 = e2.dot(d);
    const double b1 = (g22 * r1 - g12 * r2) / det, b2 = (g11 * r2 - g12 * r1) / det;
    const double h2 = std::max(0.0, (d - b1 * e1 - b2 * e2).squaredNorm());
    const double s2 = R * R - h2;
    if (s2 <= 0.0) return;
    const double w1 = std::sqrt(s2 * g22 / det), w2 = std::sqrt(s2 * g11 / det);
    lo1 = b1 - w1, hi1 = b1 + w1, lo2 = b2 - w2, hi2 = b2 + w2;
  }
  // Area shares (in sub-triangle areas): a corner of the triangle is a corner of 1
  // sub-triangle, a node inside an edge of 3, an interior node of 6.
  const double unit = model_.elements[t].area / (3.0 * m * m);
  const int i0 = std::max(0, static_cast<int>(std::floor(lo1 * m)));
  const int i1 = std::min(m, static_cast<int>(std::ceil(hi1 * m)));
  const int j0 = std::max(0, static_cast<int>(std::floor(lo2 * m)));
  for (int i = i0; i <= i1; ++i) {
    const int j1 = std::min(m - i, static_cast<int>(std::ceil(hi2 * m)));
    const int row_start = i * (m + 1) - i * (i - 1) / 2;
    for (int j = j0; j <= j1; ++j) {
      double b[3];
      b[1] = static_cast<double>(i) / m;
      b[2] = static_cast<double>(j) / m;
      b[0] = static_cast<double>(m - i - j) / m;
      const int on_edges = (i == 0) + (j == 0) + (i + j == m);
      const double w = unit * (on_edges == 0 ? 6.0 : on_edges == 1 ? 3.0 : 1.0);
      fn(row_start + j, b, w);
    }
  }
}

Vec3 FingertipContact::point(const std::vector<Vec3>& x, int tri, const double b[3]) const {
  const auto& t = tris_[tri];
  return b[0] * x[t[0]] + b[1] * x[t[1]] + b[2] * x[t[2]];
}

// The candidates of the last query (made with centre c, reach r + e beyond the sphere's
// centre, broad-phase displacement d then) hold every triangle that can come within r + m of
// a new centre c' while m + |c' - c| + (d' - d) <= e and the hierarchy was not refitted since:
// a triangle point moved at most d' from where the hierarchy has it, and the query was grown
// by d. So the broad phase is asked again only when a fingertip has moved through its margin.
bool FingertipContact::covers(const Finger& F, const Vec3& centre, double motion) const {
  return F.query_extra >= 0.0 && F.query_refits == bp_.refits() &&
         motion + (centre - F.query_at).norm() + (bp_.displacement() - F.query_disp) <= F.query_extra;
}

void FingertipContact::ensure_candidates(int f, const Vec3& centre, double motion) {
  Finger& F = fing_[f];
  if (covers(F, centre, motion)) return;
  F.query_at = centre;
  F.query_extra = p_.margin + motion;
  F.query_disp = bp_.displacement();
  F.query_refits = bp_.refits();
  F.ncand = bp_.query_sphere(centre, p_.radius + F.query_extra, F.cand.data(),
                             static_cast<int>(F.cand.size()));
}

void FingertipContact::find_samples(int f, const cloth::ClothState& s, const Vec3& proxy_at) {
  Finger& F = fing_[f];
  F.prev.swap(F.now);
  F.now.clear();
  F.gone.clear();
  const Vec3& p = integ_.proxies()[f].x;
  ensure_candidates(f, p, (proxy_at - p).norm() + h_ * vmax_);
  size_t j = 0;  // walks the last step's contacts (both lists ascend by sample id)
  for (int c = 0; c < F.ncand; ++c) {
    const int t = F.cand[c];
    double vmax = 0.0;
    for (int k = 0; k < 3; ++k) vmax = std::max(vmax, s.v[tris_[t][k]].norm());
    const double R = p_.radius + (proxy_at - p).norm() + h_ * vmax;
    for_samples_near(t, s.x, p, R, [&](int k, const double* b, double w) {
      Sample q;
      for (int i = 0; i < 3; ++i) q.b[i] = b[i];
      const Vec3 x = point(s.x, t, q.b);
      const Vec3 v = point(s.v, t, q.b);
      const double d = (x - p).norm();
      const double depth = p_.radius - d;
      const double ahead = p_.radius - (x + h_ * v - proxy_at).norm();
      if ((depth <= 0.0 && ahead <= 0.0) || d < 1e-12) return;
      q.id = first_[t] + k;
      q.tri = t;
      q.w = w;
      while (j < F.prev.size() && F.prev[j].id < q.id) ++j;
      const Sample* before = j < F.prev.size() && F.prev[j].id == q.id ? &F.prev[j] : nullptr;
      const Vec3 motion = slides(before) ? steps_.relative_motion(proxy_at - p, h_ * v) : Vec3::Zero();
      if (!place(q, x, p, motion)) return;
      if (before) {  // a contact that persists: its friction state
        q.anchor = before->anchor;
        q.slipping = before->slipping;
        q.fn = before->fn;
      }
      decide_friction(f, q);
      F.now.push_back(q);
    });
  }
}

// The contact pressure p(d) = kappa d (1 + d / d_s) over the sample's area w, linearized at the
// start of the step by its secant: the stiffness kn = w p(d0) / d0 = kappa w (1 + d0 / d_s) and
// the force f0 = kn d0, so the linear spring still lets go where the sphere's surface is. (The
// tangent, w p'(d0), lets go inside the sphere, d0^2 / (d_s + 2 d0) deep, which a long step of
// the multirate path makes millimetres: docs/contact.md, 'The model'.) A light touch feels the
// linear law kappa d (within 5% at the drum's 0.013 mm, 20% at d_s / 5); deeper it stiffens, so
// that a crease of a coarse mesh pressed at the device's force limit, which loads a line of
// samples instead of an area, stays shallow (the random two-finger runs of
// `hapticloth-bench stability`: 0.50 mm inside a fingertip with the linear law; docs/contact.md).
// A sample still outside (d0 <= 0) takes the law's slope at contact, kappa w. The multirate
// path's long steps keep the linear law: a sample pressed deeper within a 20-40 ms step is
// held by the stiffness at its start, and with the secant of the stiffening law the stability
// map's 40 ms stroke cell goes deeper into a fingertip than allowed (docs/contact.md, 'The model').
// A contact's geometry for the step, from its point x and the proxy p0 at the start. The
// penalty spring acts across the sphere's tangent plane where the sphere is expected at the end
// of the step relative to that point (at): normal n = (x - at) / |x - at|, and the depth at the
// start measured along it, depth0 = r - n . (x - p0), so the spring's depth depth0 - n . (dx -
// dp) is that plane's (the end state's geometry, as backward Euler takes its forces, eq. 8).
// Linearized about the start instead, a proxy that slides s over the step is pushed back by
// F s / r, its normals pointing from where it was (a 20 ms global step of a 30 mm/s stroke: 10%
// of the normal force). Only the slide tilts the normal: at = p0 + (I - n0 n0^T) m, n0 the
// start's normal and m the sphere's expected motion relative to the point (`motion`: the
// proxy's expected motion less the point's, h v, and none where the contact sticks, slides()).
// Taken from the proxy's whole expected motion for every contact, the stability map's strokes
// with friction 0.6 tilted the normals of points the sphere drags along by the 4-10 mm a
// 20-40 ms step moves the device, and the response model rendered a drag of up to 8 times the
// normal force (9 of the map's 36 multirate cells 2.8-7.7 mm inside the proxy, 2 before).
// Friction keeps the start's tangent plane nt = n0, where its anchor was taken
// (decide_friction, revise_friction): moved with the normal, the 25 Hz stroke's friction
// chattered. Returns false where the point is the sphere's centre (no normal).
bool FingertipContact::place(Sample& q, const Vec3& x, const Vec3& p0, const Vec3& motion) const {
  const double d0 = (x - p0).norm();
  if (d0 < 1e-12) return false;
  const Vec3 n0 = (x - p0) / d0;
  const Vec3 at = p0 + (motion - n0 * n0.dot(motion));
  const double d = (x - at).norm();
  if (d < 1e-12) return false;
  q.n = (x - at) / d;
  q.nt = n0;
  q.depth0 = p_.radius - q.n.dot(x - p0);
  linearize_pressure(q);
  q.x0 = x;
  q.anchor = x - p0;
  return true;
}

// Whether a contact is expected to slide over the step (place): without friction always; with
// it where the last step found it slipping. A new contact starts at its anchor, sticking.
bool FingertipContact::slides(const Sample* before) const {
  return !(p_.friction > 0.0) || (before && before->slipping);
}

// How deep the sphere (centre c) is past the cloth's point nearest its centre among finger f's
// candidate triangles (0 if not past), and where on the weave the fingertip presses: the point
// the contact normal through the centre meets the cloth (r.normal, towards the finger). Not the
// nearest point: a cloth wrapped round the sphere is nearly as near everywhere in the patch, and
// the nearest point jumps about in it by millimetres; nor the contacts' force-weighted centre,
// which moves in steps as samples join and leave. The ray still wobbles with the summed normal
// from tick to tick: the tactile channel's tracker integrates the slip over the cloth between
// these anchors (tactile/weave_tracker.hpp), with the cloth's velocity and material map here.
void FingertipContact::nearest_surface(int f, const cloth::ClothState& s, const Vec3& c, ProxyResult& r) const {
  const std::vector<Vec3>& x = s.x;
  const Finger& F = fing_[f];
  double best = INFINITY, hit_at = INFINITY;
  int tri = -1;
  double b[3] = {0.0, 0.0, 0.0};
  const Vec3 d = -r.normal;
  for (int i = 0; i < F.ncand; ++i) {
    const auto& t = tris_[F.cand[i]];
    const Vec3 &a = x[t[0]], &e1 = x[t[1]], &e2 = x[t[2]];
    best = std::min(best, closest_point_triangle(c, a, e1, e2).dist2);
    // The ray c + s d against the triangle (Moller and Trumbore), s >= 0.
    const Vec3 u = e1 - a, w = e2 - a, pv = d.cross(w);
    const double det = u.dot(pv);
    if (std::abs(det) < 1e-18) continue;
    const Vec3 tv = c - a;
    const double bu = tv.dot(pv) / det;
    const Vec3 qv = tv.cross(u);
    const double bv = d.dot(qv) / det, s = w.dot(qv) / det;
    if (bu < 0.0 || bv < 0.0 || bu + bv > 1.0 || s < 0.0 || s >= hit_at) continue;
    hit_at = s;
    tri = F.cand[i];
    b[0] = 1.0 - bu - bv;
    b[1] = bu;
    b[2] = bv;
  }
  r.penetration = std::isfinite(best) ? std::max(0.0, p_.radius - std::sqrt(best)) : 0.0;
  if (tri < 0 || model_.weave_uv.size() != tris_.size()) return;
  const auto& uv = model_.weave_uv[static_cast<size_t>(tri)];
  r.weave_u = b[0] * uv[0][0] + b[1] * uv[1][0] + b[2] * uv[2][0];
  r.weave_v = b[0] * uv[0][1] + b[1] * uv[1][1] + b[2] * uv[2][1];
  const auto& t = tris_[static_cast<size_t>(tri)];
  auto corner = [&](int k) { return Eigen::Vector2d(uv[k][0], uv[k][1]); };
  r.weave_map = tactile::weave_map(x[t[0]], x[t[1]], x[t[2]], corner(0), corner(1), corner(2));
  r.surface_velocity = b[0] * s.v[t[0]] + b[1] * s.v[t[1]] + b[2] * s.v[t[2]];
}


// Samples of the candidate triangles that would end more than kAddDepth inside the sphere
// (centre p0 at the start of the step, p1 at its end) join the contacts, in id order.
// Returns true if any did.
bool FingertipContact::add_contacts(int f, const std::vector<Vec3>& x_new, const Vec3& p0,
                                    const Vec3& p1) {
  Finger& F = fing_[f];
  size_t j = 0;
  const size_t nold = F.now.size();
  for (int c = 0; c < F.ncand; ++c) {
    const int t = F.cand[c];
    for_samples_near(t, x_new, p1, p_.radius, [&](int k, const double* b, double w) {
      const int id = first_[t] + k;
      while (j < nold && F.now[j].id < id) ++j;
      if (j < nold && F.now[j].id == id) return;
      Sample q;
      for (int i = 0; i < 3; ++i) q.b[i] = b[i];
      const Vec3 x1 = point(x_new, t, q.b);
      if (p_.radius - (x1 - p1).norm() <= kAddDepth) return;
      // Released earlier in this step: back with the friction state it had, where the step's
      // rules say so (ContactStepRules::rejoins_with_state).
      const auto back = std::find_if(F.gone.begin(), F.gone.end(), [&](const Sample& g) { return g.id == id; });
      if (back != F.gone.end() && steps_.rejoins_with_state()) {
        F.now.push_back(*back);
        F.gone.erase(back);
        rejoin(F.now.back(), x1 - point(s0_->x, t, q.b) - (p1 - p0));
        return;
      }
      q.id = id;
      q.tri = t;
      q.w = w;
      const Vec3 x0 = point(s0_->x, t, q.b);
      const Vec3 motion = slides(nullptr) ? steps_.relative_motion(p1 - p0, x1 - x0) : Vec3::Zero();
      if (!place(q, x0, p0, motion)) return;
      decide_friction(f, q);
      F.now.push_back(q);
    });
  }
  if (F.now.size() == nold) return false;
  merge_added(F, nold);
  return true;
}

}  // namespace hapticloth::haptics
