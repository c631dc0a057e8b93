#include "haptics/fingertip_contact.hpp"

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
#include "haptics/geometry.hpp"
#include "tactile/weave_tracker.hpp"

namespace hapticloth::haptics {

namespace {
using cloth::Mat3;

// A sample that would pull harder than this (N per m^2 of its area per kappa, i.e. metres of
// negative depth) is dropped; a point deeper than kAddDepth inside a sphere is added.
constexpr double kPullDepth = 1e-6;  // m
constexpr double kAddDepth = 5e-6;   // m
// Re-solves of a step that may release contacts (see revise()).
constexpr int kFreeRevisions = 12;
// m/s: how fast a change of the refined compliance may move the fingertip through the refined
// cloth (approach_refined_compliance): 10 mm/s, a slow press's speed, so that a 7 mm change
// takes 0.7 s and a tick's jump is 10 um (k dp^2 / 2 = 0.04 uJ at 800 N/m).
constexpr double kRefinedDepthRate = 0.01;
}  // namespace

// kResolveShare: released contacts and friction corrections ask for a re-solve once their
// forces add up to this share of the finger's normal force; smaller ones take effect from the
// next step. 1% of the normal force is a tenth of the force a person can tell apart (7-10%).
// At 0.2%, half the steps of a held pinch were solved twice: contacts at the rim of the pinch,
// where the normal force goes to zero, switching between sticking and sliding as the hanging
// cloth sways.
// kResolveFloor: never for less than this force in all: Weber's law fails near zero, where what
// a fingertip tells apart is the smallest force it detects at all, 29-44 mN (King, Donlin and
// Hannaford, "Perceptual thresholds for single vs. multi-finger haptic interaction", 2010). A
// thirtieth of that keeps a finger under 0.1 N (a light touch, a cloth sliding out of opening
// fingers) from being solved again for friction changes of tenths of a millinewton.
double FingertipContact::coulomb_bound(double normal_force, double mu) {
  return std::max(kResolveShare * normal_force, kResolveFloor) + kConeTolerance * mu * normal_force;
}

FingertipContact::FingertipContact(const cloth::ClothModel& model,
                                   const std::vector<std::array<int, 3>>& tris, int fingers,
                                   const ContactParams& p, cloth::Integrator& integ)
    : model_(model),
      tris_(tris),
      fingers_(fingers),
      p_(p),
      integ_(integ),
      bp_(model.rest_positions, tris),
      // Direct coupling's short steps (cloth::ContactSteps) defer their late slide-to-stick
      // switches to the next step (revise()), their pressure law stiffens with depth (linearize_pressure),
      // their contacts are one-sided for the integrator's line search (make_spring) and come back
      // from a release with their state (add_contacts).
      short_steps_(integ.config().contact_steps == cloth::ContactSteps::Short) {
  if (!devices::valid_finger_count(fingers_))
    throw std::invalid_argument("fingertip contact: a device has " + std::to_string(devices::kMinFingers) +
                                " to " + std::to_string(devices::kMaxFingers) + " fingers, not " +
                                std::to_string(fingers_));
  if (static_cast<int>(integ_.proxies().size()) < fingers_)
    throw std::invalid_argument("fingertip contact: the integrator needs a proxy per finger");
  if (!(p_.radius > 0.0) || !(p_.pressure_stiffness > 0.0) || !(p_.coupling_stiffness > 0.0))
    throw std::invalid_argument("fingertip contact: radius, stiffnesses must be > 0");
  spacing_ = p_.sample_spacing > 0.0 ? p_.sample_spacing : p_.radius / 8.0;
  // Subdivide each triangle so that its sub-triangles' edges are at most the spacing: every
  // point of the cloth is then within spacing / sqrt(3) of a sample (a node).
  const int nt = static_cast<int>(tris_.size());
  sub_.resize(nt);
  first_.resize(nt + 1, 0);
  for (int t = 0; t < nt; ++t) {
    double e = 0.0;
    for (int k = 0; k < 3; ++k)
      e = std::max(e, (model_.rest_positions[tris_[t][k]] - model_.rest_positions[tris_[t][(k + 1) % 3]]).norm());
    sub_[t] = std::max(1, static_cast<int>(std::ceil(e / spacing_ - 1e-9)));
    first_[t + 1] = first_[t] + (sub_[t] + 1) * (sub_[t] + 2) / 2;
  }
  for (int f = 0; f < fingers_; ++f) {
    fing_[f].cand.resize(nt);
    fing_[f].now.reserve(1024);
    fing_[f].prev.reserve(1024);
    fing_[f].gone.reserve(1024);
  }
  merged_.reserve(1024);
  integ_.point_springs().reserve(2048);
  integ_.set_contacts(this);
}

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
      if (!place(q, x, p, short_steps_ ? p : proxy_at)) return;
      while (j < F.prev.size() && F.prev[j].id < q.id) ++j;
      if (j < F.prev.size() && F.prev[j].id == q.id) {  // a contact that persists: its friction state
        q.anchor = F.prev[j].anchor;
        q.slipping = F.prev[j].slipping;
        q.fn = F.prev[j].fn;
      }
      decide_friction(f, q);
      F.now.push_back(q);
    });
  }
}

// The contact pressure p(d) = kappa d (1 + d / d_s) over the sample's area w, linearized at the
// start of the step by its secant: the stiffness kn = w p(d0) / d0 = kappa w (1 + d0 / d_s) and
// the force f0 = kn d0, so the linear spring still lets go where the sphere's surface is. (The
// tangent, w p'(d0), let go inside the sphere, d0^2 / (d_s + 2 d0) deep: the multirate path's
// 20 ms pinch ended steps with the cloth 2.5 mm inside a fingertip.) A light touch feels the
// linear law kappa d (within 5% at the drum's 0.013 mm, 20% at d_s / 5); deeper it stiffens, so
// that a crease of a coarse mesh pressed at the device's force limit, which loads a line of
// samples instead of an area, stays shallow (the random two-finger runs of
// `hapticloth-bench stability`: 0.50 mm inside a fingertip with the linear law; docs/contact.md).
// A sample still outside (d0 <= 0) takes the law's slope at contact, kappa w. The multirate
// path's long steps keep the linear law: a sample pressed deeper within a 20-40 ms step is
// held by the stiffness at its start, and with the secant of the stiffening law the 40 ms stroke
// cell of the stability map went 3.7 mm into a fingertip (2 mm allowed).
// A contact's geometry for the step, from its point x and the proxy p0 at the start. The
// penalty spring acts across the sphere's tangent plane where the proxy is expected at the end
// of the step (at): normal n = (x - at) / |x - at|, and the depth at the start measured along
// it, depth0 = r - n . (x - p0), so the spring's depth depth0 - n . (dx - dp) is that plane's
// (the end state's geometry, as backward Euler takes its forces, eq. 8). Linearized about the
// start instead, a proxy that slides s over the step is pushed back by F s / r, its normals
// pointing from where it was (a 20 ms global step of a 30 mm/s stroke: 10% of the normal
// force). Friction keeps the start's tangent plane nt, where its anchor was taken
// (decide_friction, revise_friction): moved with the normal, the 25 Hz stroke's friction
// chattered. Returns false where the point is the sphere's centre (no normal).
bool FingertipContact::place(Sample& q, const Vec3& x, const Vec3& p0, const Vec3& at) const {
  const double d = (x - at).norm();
  if (d < 1e-12) return false;
  q.n = (x - at) / d;
  const double d0 = (x - p0).norm();
  q.nt = d0 > 1e-12 ? Vec3((x - p0) / d0) : q.n;
  q.depth0 = p_.radius - q.n.dot(x - p0);
  linearize_pressure(q);
  q.x0 = x;
  q.anchor = x - p0;
  return true;
}

void FingertipContact::linearize_pressure(Sample& q) const {
  const double kw = p_.pressure_stiffness * q.w, d = std::max(q.depth0, 0.0);
  q.kn = short_steps_ ? kw * (1.0 + d / p_.stiffening_depth) : kw;
  q.f0 = q.kn * q.depth0;
}

// The contact as a point spring (the cloth's side; the proxy gets minus it): the penalty
// pressure over the sample's area along the sphere normal (linearize_pressure), and Coulomb
// friction: a tangential spring to the anchor while it sticks, a force of mu x its normal force
// against the slide while it slides. K = kn n n^T, plus kappa w (I - n n^T) while sticking. In a
// short step (direct coupling) it is one-sided for the integrator's line search: it acts while
// its depth d0 - n . r > 0. The multirate path's long steps leave the line search off (kn 0
// there): they revise their set as before.
void FingertipContact::make_spring(int f, const Sample& q, cloth::PointSpring& sp) const {
  const double k = p_.pressure_stiffness * q.w;
  sp.tri = q.tri;
  for (int i = 0; i < 3; ++i) sp.b[i] = q.b[i];
  sp.proxy = f;
  sp.key = q.id;
  sp.kn = short_steps_ ? q.kn : 0.0;
  sp.depth0 = q.depth0;
  sp.n = q.n;
  sp.f = q.f0 * q.n;
  sp.K = q.kn * q.n * q.n.transpose();
  if (q.sliding) {
    sp.f += q.slide;
    return;
  }
  const Mat3 Pt = Mat3::Identity() - q.nt * q.nt.transpose();
  sp.f -= k * (Pt * (q.x0 - p0_[f] - q.anchor));
  sp.K += k * Pt;
}

// Stick or slide at the start of the step: the stick spring's force against mu f_n.
void FingertipContact::decide_friction(int f, Sample& q) const {
  const double k = p_.pressure_stiffness * q.w;
  const Mat3 Pt = Mat3::Identity() - q.nt * q.nt.transpose();
  const Vec3 ft = -k * (Pt * (q.x0 - p0_[f] - q.anchor));
  const double lim = p_.friction * std::max(q.f0, 0.0);
  const double ftn = ft.norm();
  q.sliding = ftn > lim;
  q.slide = q.sliding ? Vec3(ft * (lim / ftn)) : Vec3::Zero();
}

// The normal force of a contact's linearized spring at the end of the step (rel_step: the
// point's motion relative to the proxy), N; negative if it would pull.
double FingertipContact::normal_at_end(const Sample& q, const Vec3& rel_step) const {
  return q.f0 - q.kn * q.n.dot(rel_step);
}

// Coulomb at the end of the solved step (rel_step: the point's motion relative to the proxy):
// a sticking contact whose spring would leave the friction cone slides instead, and a sliding
// one takes mu x its end normal force. Returns how much its force changed, N: the change that
// asks for a re-solve. With `defer`, a sliding contact keeps sliding (only stick-to-slide
// switches, and that direction alone cannot cycle); its magnitude still follows its normal
// force, a fixed point the re-solves converge to.
double FingertipContact::revise_friction(Sample& q, const Vec3& p0, const Vec3& rel_step,
                                          bool defer) const {
  const double k = p_.pressure_stiffness * q.w;
  const double lim = p_.friction * std::max(normal_at_end(q, rel_step), 0.0);
  const double tol = kConeTolerance * lim + 1e-9;
  if (!q.sliding) {
    const Mat3 Pt = Mat3::Identity() - q.nt * q.nt.transpose();
    const Vec3 ft = -k * (Pt * (q.x0 - p0 + rel_step - q.anchor));
    const double ftn = ft.norm();
    if (ftn <= lim + tol) return 0.0;
    q.sliding = true;
    q.slide = ft * (lim / ftn);
    return ftn - lim;
  }
  // Friction never drives the slide: if the point moved along the friction force relative to
  // the sphere, the contact sticks (the stick spring starting from the sliding force), so
  // the direction does not flip from step to step.
  const Mat3 Pt = Mat3::Identity() - q.nt * q.nt.transpose();
  const Vec3 slip = Pt * rel_step;
  if (!defer && slip.dot(q.slide) > 0.0) {
    q.sliding = false;
    q.anchor = q.x0 - p0 + Pt * q.slide / k;
    // Sticking, the contact would resist this step's slip with k |slip| more, and its force
    // stays in the cone: the change is at most the cone's width.
    return std::min(k * slip.norm(), 2.0 * lim + tol);
  }
  const double sn = q.slide.norm();
  if (std::abs(sn - lim) <= tol) return 0.0;
  if (sn > 0.0) {
    q.slide *= lim / sn;
  } else if (short_steps_) {
    // A slide scaled to nothing while its normal force was (a contact whose end state pulled
    // at an earlier re-solve) has no direction left: kinetic friction opposes the point's slip
    // over the sphere. Kept at zero, the contact would slide frictionless for the rest of the
    // step however hard it pressed again, and the stroke's friction would fall 5% short of
    // Coulomb's on such ticks. The multirate path's long steps keep it at zero: the global step
    // is only what the local model follows there, and its response model, following the
    // steps this rule gives, predicts the finger leaving the cloth mid-stroke (the 25 Hz
    // stroke's force falling to a quarter within a global step).
    const double sl = slip.norm();
    if (sl <= 0.0) return 0.0;
    q.slide = slip * (-lim / sl);
  }
  return std::abs(sn - lim);
}

void FingertipContact::rebuild_springs() {
  auto& springs = integ_.point_springs();
  springs.clear();
  for (int f = 0; f < fingers_; ++f)
    for (const Sample& q : fing_[f].now) {
      springs.emplace_back();
      make_spring(f, q, springs.back());
    }
}

void FingertipContact::begin_step(const cloth::ClothState& s,
                                  const std::array<FingerTarget, kMaxFingers>& in, double h) {
  h_ = h;
  s0_ = &s;
  revisions_ = 0;
  bp_.update(s.x);
  double v2 = 0.0;
  for (const Vec3& v : s.v) v2 = std::max(v2, v.squaredNorm());
  vmax_ = std::sqrt(v2);
  for (int f = 0; f < fingers_; ++f) {
    cloth::ProxyNode& P = integ_.proxies()[f];
    approach_refined_compliance(f);
    P.stiffness = 1.0 / (1.0 / p_.coupling_stiffness + refined_c_[f]);
    P.axis_stiffness = 0.0;
    valid_[f] = in[f].valid;
    if (!in[f].valid) {  // no device sample: the proxy stays where it is, touching nothing
      P.target = P.x;
      P.target_velocity.setZero();
      P.damping = 0.0;
      device_target_[f] = P.x;
      fing_[f].prev.clear();
      fing_[f].now.clear();
      fing_[f].gone.clear();
      fing_[f].ncand = 0;
      fing_[f].query_extra = -1.0;
      seen_[f] = false;
      continue;
    }
    const bool first = !seen_[f];
    if (first) {  // the first sample, or back after an absence: the proxy starts at the fingertip
      P.x = in[f].position;
      tip_[f] = P.x;
      last_disp_[f].setZero();
      seen_[f] = true;
    }
    p0_[f] = P.x;
    set_coupling_target(P, in[f]);
    P.damping = p_.coupling_damping;
    device_target_[f] = P.target;
    refined_axis_[f].setZero();
    if (short_steps_ && refined_c_[f] > 0.0) couple_through_fingertip(f, P);
    find_samples(f, s, expected_proxy(f, first));
  }
  rebuild_springs();
}

// Where proxy f is expected at the end of the step (after set_coupling_target). In a short step
// (direct coupling, 1 ms) it moves a few hundredths of a millimetre: as in the last step. A long
// step of the multirate path moves it as its target moved since the last step (the massless
// proxy follows the device; exact for a steady stroke): its own last displacement is no guide
// there, as a contact that lets go moves it millimetres in one long step, and a prediction that
// far off puts the contacts' normals (place) on the wrong side.
Vec3 FingertipContact::expected_proxy(int f, bool first) {
  const cloth::ProxyNode& P = integ_.proxies()[f];
  const Vec3 moved = first ? Vec3::Zero() : Vec3(P.target - last_target_[f]);
  last_target_[f] = P.target;
  return P.x + (short_steps_ ? last_disp_[f] : moved);
}

// The refined compliance moves towards the refinement's latest at most as fast as it moves the
// fingertip through the refined cloth, c F_n, by kRefinedDepthRate: a child built under a
// pressing finger, or re-centred, puts the fingertip millimetres deeper (on a 25 mm mesh the
// pinch's fingertips went 7 mm deeper at once), and a proxy that jumps while the force is held
// over a tick is felt as a force step and gives the coupling k dp^2 / 2 it never got (the
// passivity observer saw 35 mJ in the pinch's first 50 ms).
void FingertipContact::approach_refined_compliance(int f) {
  const double target = refined_target_[f], now = refined_c_[f];
  const double fn = std::max(out_[f].force.dot(out_[f].normal), 0.0);
  const double most = fn > 0.0 ? kRefinedDepthRate * h_ / fn : std::abs(target - now);
  refined_c_[f] = now + std::clamp(target - now, -most, most);
}

// With a refined compliance c the chain is cloth -[c]- fingertip -[k || b]- device: the coupling's
// damper acts across the fingertip, not across the global proxy. Over a backward Euler step the
// damper is a spring b/h anchored at the fingertip's last position moved by the device's
// motion, so k || b is the spring k1 = k + b/h towards
//     a = (k T + (b/h) (tip + h v_T)) / k1
// (T the device's target), and in series with c the proxy P gets the spring
// 1 / (1/k1 + c) towards a, undamped: F = (a - P) / (1/k1 + c), and the fingertip sits at
// a - F / k1 = P + c F. With c = 0 this is the coupling as the integrator applies it (k to T,
// b to v_T). Put the damper on P instead (k_eff = 1 / (1/k + c) with b in parallel), a large
// c leaves the damper (b/h = 1000 N/m at 1 ms) far stiffer than the spring, and P, pushed
// through the slack cloth by the other finger of a pinch, dragged a fingertip whose spring k
// no longer carried the force the device rendered, and the coupling's energy balance saw
// energy created (docs/contact.md, "the chain through the fingertip").
//
// The child measures how much deeper the fingertip sits along the contact's normal, so c acts
// along the last step's normal n alone: the spring is k1 across it and 1 / (1/k1 + c) along it.
// Isotropic, a slack cloth's compliance left the proxy a spring of a few N/m sideways, and a
// sticking contact dragged it with the cloth, far beyond the friction cone.
void FingertipContact::couple_through_fingertip(int f, cloth::ProxyNode& P) {
  const double kb = p_.coupling_damping / h_;
  const double k1 = p_.coupling_stiffness + kb;
  P.target = (p_.coupling_stiffness * P.target + kb * (tip_[f] + h_ * P.target_velocity)) / k1;
  P.stiffness = k1;
  P.damping = 0.0;
  refined_axis_[f] = out_[f].normal;
  if (refined_axis_[f].squaredNorm() > 0.0) {
    P.axis = refined_axis_[f];
    P.axis_stiffness = 1.0 / (1.0 / k1 + refined_c_[f]);
  }
}

// The coupling's target for proxy P: the device's fingertip. But when the spring would ask
// more than the device can render (a hand pushing on through the cloth past the device's
// force limit, or a long global step of the multirate path dragging the cloth after a fast
// finger), the target is pulled back towards the proxy until the spring asks exactly that
// limit. So the cloth gets no more than the device can render from the spring (the gate
// clamps the rendered force to the same limit), and a saturated push cannot press the cloth
// into the fingertip with tens of newtons. The damper still follows the device's velocity:
// scaling it back too let the multirate path's global proxies trail a fast finger
// (`hapticloth-bench stability`: 28 of 36 multirate cells instead of 34).
void FingertipContact::set_coupling_target(cloth::ProxyNode& P, const FingerTarget& device) const {
  const Vec3 reach = device.position - P.x;
  const double ask = P.stiffness * reach.norm();
  const double scale = p_.max_force > 0.0 && ask > p_.max_force ? p_.max_force / ask : 1.0;
  P.target = P.x + scale * reach;
  P.target_velocity = device.velocity;
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
      // Released earlier in this short step: back with the friction state it had. Fresh, it
      // would stick to where it was at the start, slide, be released and come back sticking
      // again: the cycle a fast stroke's rim samples ran to the revision cap.
      const auto back = std::find_if(F.gone.begin(), F.gone.end(), [&](const Sample& g) { return g.id == id; });
      if (back != F.gone.end() && short_steps_) {
        F.now.push_back(*back);
        F.gone.erase(back);
        rejoin(F.now.back(), x1 - point(s0_->x, t, q.b) - (p1 - p0));
        return;
      }
      q.id = id;
      q.tri = t;
      q.w = w;
      if (!place(q, point(s0_->x, t, q.b), p0, short_steps_ ? p0 : p1)) return;
      decide_friction(f, q);
      F.now.push_back(q);
    });
  }
  if (F.now.size() == nold) return false;
  merge_added(F, nold);
  return true;
}

// A released contact back in the set (rel: its point's motion relative to the proxy over the
// solved step): a slide takes mu x its normal force there, not the force it had when released
// (one touching again has almost none).
void FingertipContact::rejoin(Sample& q, const Vec3& rel) const {
  q.release = false;
  if (!q.sliding) return;
  const double lim = p_.friction * std::max(normal_at_end(q, rel), 0.0), sn = q.slide.norm();
  q.slide = sn > 0.0 ? Vec3(q.slide * (lim / sn)) : Vec3::Zero();
}

// At the line search's point (short of a solve: Integrator::revise_contacts stopped the re-solve
// where a released contact comes back to its surface), contacts released earlier in the step
// whose linearized spring would push, or just touch, join the contacts again, with the state
// they had: a tie that belongs in the set. Otherwise the set is unchanged there, and the step
// ends at the re-solve with the contact back inside. Only there: re-added on every revision,
// the ties of a slow stroke's rim left contacts with next to no normal force holding their
// friction (the per-contact Coulomb error's p99 3.4%, its worst 31%). Returns true if any did.
bool FingertipContact::restore_touching(int f, const std::vector<Vec3>& x_new, const Vec3& dp) {
  Finger& F = fing_[f];
  const size_t nold = F.now.size();
  auto back = [&](Sample& q) {
    const Vec3 rel = point(x_new, q.tri, q.b) - q.x0 - dp;
    if (normal_at_end(q, rel) < -kPullDepth * q.kn) return false;
    F.now.push_back(q);
    rejoin(F.now.back(), rel);
    return true;
  };
  F.gone.erase(std::remove_if(F.gone.begin(), F.gone.end(), back), F.gone.end());
  if (F.now.size() == nold) return false;
  std::sort(F.now.begin() + nold, F.now.end(), [](const Sample& a, const Sample& b) { return a.id < b.id; });
  merge_added(F, nold);
  return true;
}

// F.now's contacts from nold on (ascending by id) merged into those before them, through a buffer
// reserved at construction: std::inplace_merge allocates one on every call (about ten a step
// of a fast strike; test_fingertip_contact FastStrikeConvergesWithTheClothOutside).
void FingertipContact::merge_added(Finger& F, size_t nold) {
  merged_.clear();
  std::merge(F.now.begin(), F.now.begin() + static_cast<std::ptrdiff_t>(nold),
             F.now.begin() + static_cast<std::ptrdiff_t>(nold), F.now.end(), std::back_inserter(merged_),
             [](const Sample& a, const Sample& b) { return a.id < b.id; });
  F.now.swap(merged_);
}

bool FingertipContact::revise(const std::vector<Vec3>& x_new,
                              const std::vector<cloth::ProxyNode>& proxies, bool short_of_solve,
                              bool same_candidate) {
  // The first kFreeRevisions re-solves of a step may release contacts; after them the
  // contact set only grows (friction is still revised), so no sample is left inside a sphere
  // at the end. Without that, a step whose new contacts start outside the sphere can cycle
  // (add five, release seven, add ten, ...) up to the revision cap and end with the cloth
  // inside. Twelve free revisions leave the multirate path's 20 ms pinch and 25 Hz stroke as
  // they were (fewer, or freezing friction too, let the cloth end 0.4-1.2 mm inside a
  // fingertip in the pinch and the stroke's friction chatter).
  // A short step (direct coupling) also defers its late slide-to-stick switches: after the free
  // revisions a contact that slides stays sliding to the next step, 1 ms later (its magnitude
  // still follows its normal force). Otherwise contacts at the cone's edge flip between stick
  // and slide until the revision cap, and the step ends before the samples that the last solve
  // pushed inside are added. A long global step of the multirate path holds its friction state
  // for the whole step and keeps revising it (deferring there let the 20 ms pinch carry 10% less
  // than the weight). The integrator's line search keeps whole re-solves from overshooting
  // (Integrator::revise_contacts; a step revised on local settles has none); contacts released
  // earlier in the step come back with their state (add_contacts, restore_touching).
  // A re-solve that left the solution as it was (a PCG re-solve that took no iteration) hands
  // back the same candidate: on it, a contact whose friction the solver cannot resolve (a change
  // under its tolerance) would switch between sticking and sliding until the free revisions ran
  // out, each switch a re-solve that again takes no iteration (753 of the 2547 re-solves of the 4050-triangle square's stroke,
  // `hapticloth-bench step --script`). So the free revisions end there.
  if (same_candidate) revisions_ = std::max(revisions_, kFreeRevisions);
  const bool settle = revisions_ < kFreeRevisions;
  const bool defer = !settle && short_steps_;
  ++revisions_;
  bool changed = false;
  for (int f = 0; f < fingers_; ++f) {
    if (!valid_[f]) continue;
    Finger& F = fing_[f];
    const Vec3& p0 = proxies[f].x;
    const Vec3 dp = proxies[f].displacement;
    const Vec3 p1 = p0 + dp;
    ensure_candidates(f, p0, dp.norm() + h_ * vmax_);  // the solved step may reach further than foreseen
    if (F.ncand == 0 && F.now.empty()) continue;
    const bool restored = short_of_solve && restore_touching(f, x_new, dp);
    // Contacts that would pull at the end of the step are released; points that would end
    // inside the sphere become contacts; Coulomb's law is checked on the solved step. The step
    // is solved again for every new contact, and for released contacts and friction
    // corrections once their forces add up to kResolveShare of the finger's normal force at the
    // end of the step, and at least kResolveFloor (smaller ones are applied from the next step
    // on: the contact set and friction state move with them).
    double pulled = 0.0, fchange = 0.0, fscale = 0.0;
    for (Sample& q : F.now) {
      const Vec3 rel = point(x_new, q.tri, q.b) - q.x0 - dp;
      const double fn1 = normal_at_end(q, rel);
      fscale += std::max(fn1, 0.0);
      q.release = settle && fn1 < -kPullDepth * q.kn;
      if (q.release)
        pulled += -fn1;
      else
        fchange += revise_friction(q, p0, rel, defer);
    }
    const bool added = add_contacts(f, x_new, p0, p1);
    changed = changed || restored || added || pulled + fchange > std::max(kResolveShare * fscale, kResolveFloor);
  }
  if (!changed) return false;
  for (int f = 0; f < fingers_; ++f) {
    auto& now = fing_[f].now;
    for (const Sample& q : now)
      if (q.release) fing_[f].gone.push_back(q);
    now.erase(std::remove_if(now.begin(), now.end(), [](const Sample& q) { return q.release; }), now.end());
  }
  rebuild_springs();
  return true;
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

void FingertipContact::end_step(const cloth::ClothState& s) {
  size_t next = 0;
  for (int f = 0; f < fingers_; ++f) {
    ProxyResult& r = out_[f];
    const cloth::ProxyNode& P = integ_.proxies()[f];
    r = ProxyResult{};
    r.proxy = P.x;
    r.target = device_target_[f];
    r.target_velocity = P.target_velocity;
    r.coupling_stiffness = P.stiffness;
    if (!valid_[f]) {  // no device sample this step
      last_disp_[f].setZero();
      continue;
    }
    r.valid = true;
    last_disp_[f] = P.displacement;
    Finger& F = fing_[f];
    Vec3 on_cloth = Vec3::Zero(), nsum = Vec3::Zero(), csum = Vec3::Zero();
    double fmax = -1.0, fpos = 0.0;
    bool all_slip = true;
    const auto& springs = integ_.point_springs();  // as solved: F.now in order, finger by finger
    for (Sample& q : F.now) {
      const cloth::PointSpring& sp = springs[next++];
      const Vec3 x1 = point(s.x, q.tri, q.b);
      // What the cloth got in the step: the spring linearized at the start, at the end state.
      const Vec3 got = sp.f - sp.K * (x1 - q.x0 - P.displacement);
      on_cloth += got;
      const double fn = got.dot(q.n);
      const Vec3 ft = got - fn * q.n;
      r.normal_force += std::abs(fn);
      r.friction_force += ft.norm();
      nsum += fn * q.n;
      csum += std::max(fn, 0.0) * x1;
      fpos += std::max(fn, 0.0);
      if (fn > fmax) {
        fmax = fn;
        r.triangle = q.tri;
        for (int i = 0; i < 3; ++i) r.bary[i] = q.b[i];
      }
      // Coulomb return mapping at the end state: a stretched stick spring beyond mu f_n slides
      // its anchor back onto the friction cone.
      const double k = p_.pressure_stiffness * q.w;
      const Mat3 Pt = Mat3::Identity() - q.nt * q.nt.transpose();
      const Vec3 rel = x1 - P.x;
      const Vec3 d = Pt * (rel - q.anchor);
      const double lim = p_.friction * std::max(fn, 0.0);
      const double dn = d.norm();
      q.slipping = k * dn > lim;
      if (q.slipping && dn > 0.0) q.anchor += d * (1.0 - lim / (k * dn));
      q.fn = fn;
      all_slip = all_slip && (q.slipping || fn <= 0.0);
    }
    r.points = static_cast<int>(F.now.size());
    r.in_contact = r.points > 0;
    r.slipping = r.in_contact && all_slip;
    r.force = -on_cloth;
    const double nn = nsum.norm();
    r.normal = nn > 0.0 ? Vec3(-nsum / nn) : Vec3::Zero();
    r.contact = fpos > 0.0 ? Vec3(csum / fpos) : P.x;
    for (const Sample& q : F.now) {  // the patch: its farthest pressing sample from its centre, across the normal
      if (!(q.fn > 0.0)) continue;
      const Vec3 d = point(s.x, q.tri, q.b) - r.contact;
      r.patch_radius = std::max(r.patch_radius, (d - d.dot(r.normal) * r.normal).norm());
    }
    // With local refinement the fingertip sits beyond the global proxy by the compliance the
    // global mesh lacks, in series with the coupling: c F beyond it, where the coupling alone
    // carries the force F (along the step's axis with direct coupling, couple_through_fingertip;
    // isotropic on the multirate path, whose proxies have the spring 1 / (1/k + c)). Reported
    // there, the coupling's spring k (proxy - target) is what the passivity controller's energy
    // balance needs.
    const Vec3 series = short_steps_ ? Vec3(refined_axis_[f] * refined_axis_[f].dot(r.force)) : r.force;
    r.proxy = P.x - refined_c_[f] * series;
    tip_[f] = r.proxy;
    nearest_surface(f, s, P.x, r);
    max_pen_ = std::max(max_pen_, r.penetration);
    samples_in_contact_ += r.points;
  }
}

}  // namespace hapticloth::haptics
