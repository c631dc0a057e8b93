// The fingertip's contact with the global cloth (fingertip_contact.hpp): a step's beginning and
// end, and the coupling to the device through the proxy. Where the fingertip meets the cloth is
// in fingertip_samples.cpp; the contact springs, their friction and the active set in
// fingertip_springs.cpp.
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
using cloth::Mat3;

// m/s: how fast a change of the refined compliance may move the fingertip through the refined
// cloth (approach_refined_compliance): 10 mm/s, a slow press's speed, so that a 7 mm change
// takes 0.7 s and a tick's jump is 10 um (k dp^2 / 2 = 0.04 uJ at 800 N/m).
constexpr double kRefinedDepthRate = 0.01;
}  // namespace

// kResolveShare: released contacts and friction corrections ask for a re-solve once their
// forces add up to this share of the finger's normal force; smaller ones take effect from the
// next step. 1% of the normal force is a tenth of the force a person can tell apart (7-10%).
// A smaller share re-solves the steps of a held pinch for contacts at its rim, where the normal
// force goes to zero, switching between sticking and sliding as the hanging cloth sways
// (docs/contact.md, 'The model').
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
      steps_(contact_step_rules(integ.config().contact_steps)) {
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
    if (steps_.couples_through_fingertip() && refined_c_[f] > 0.0) couple_through_fingertip(f, P);
    find_samples(f, s, expected_proxy(f, first));
  }
  rebuild_springs();
}

// Where proxy f is expected at the end of the step (after set_coupling_target): as its last
// step moved it, or as its target moved since (ContactStepRules::expected_proxy).
Vec3 FingertipContact::expected_proxy(int f, bool first) {
  const cloth::ProxyNode& P = integ_.proxies()[f];
  const Vec3 moved = first ? Vec3::Zero() : Vec3(P.target - last_target_[f]);
  last_target_[f] = P.target;
  return steps_.expected_proxy(P.x, last_disp_[f], moved);
}

// The refined compliance moves towards the refinement's latest at most as fast as it moves the
// fingertip through the refined cloth, c F_n, by kRefinedDepthRate: a child built under a
// pressing finger, or re-centred, puts the fingertip millimetres deeper, and a proxy that jumps
// while the force is held over a tick is felt as a force step and gives the coupling k dp^2 / 2
// it never got (docs/contact.md, 'Local refinement under the fingertips').
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
// The child measures how much deeper the fingertip sits, so c acts along one axis a alone: the
// spring is k1 across it and 1 / (1/k1 + c) along it. Isotropic, a slack cloth's compliance
// left the proxy a spring of a few N/m sideways, and a sticking contact dragged it with the
// cloth, far beyond the friction cone. The axis is the refined membrane's normal at the contact
// (the direction the child's cloth pushes its sphere, RefinedContact::push). Along the coarse
// facets' normal instead (the step's contact normal, tilted from the membrane's near a vertex),
// a press straight down moved the device across the axis, where k1 holds it, and the sticking
// contact rendered a sideways force the smooth membrane does not have (docs/contact.md, 'The
// axis of the compliance'). Until the child has settled once, the step's normal.
void FingertipContact::couple_through_fingertip(int f, cloth::ProxyNode& P) {
  const double kb = p_.coupling_damping / h_;
  const double k1 = p_.coupling_stiffness + kb;
  P.target = (p_.coupling_stiffness * P.target + kb * (tip_[f] + h_ * P.target_velocity)) / k1;
  P.stiffness = k1;
  P.damping = 0.0;
  refined_axis_[f] = refined_push_[f].squaredNorm() > 0.0 ? refined_push_[f] : out_[f].normal;
  if (refined_axis_[f].squaredNorm() > 0.0) {
    P.axis = refined_axis_[f];
    P.axis_stiffness = 1.0 / (1.0 / k1 + refined_c_[f]);
  }
  limit_chain_force(P);
}

// The device's force limit on the chain through the fingertip: set_coupling_target pulled the
// target back with the spring before the chain was formed (1 / (1/k + c), soft when c is
// large), but across the axis the chain is k1 = k + b/h, stiffer than k. A fast finger far
// from its proxy then asked the cloth for tens of newtons across the contact (k1 times the
// reach), and a random two-finger stroke's step blew up (docs/contact.md, 'The chain through
// the fingertip'). So the target is pulled back again until the chain's spring K (a - P) asks
// no more than the limit.
void FingertipContact::limit_chain_force(cloth::ProxyNode& P) const {
  if (!(p_.max_force > 0.0)) return;
  const double ask = (P.stiffness_matrix() * (P.target - P.x)).norm();
  if (ask > p_.max_force) P.target = P.x + (p_.max_force / ask) * (P.target - P.x);
}

// The coupling's target for proxy P: the device's fingertip. But when the spring would ask
// more than the device can render (a hand pushing on through the cloth past the device's
// force limit, or a long global step of the multirate path dragging the cloth after a fast
// finger), the target is pulled back towards the proxy until the spring asks exactly that
// limit. So the cloth gets no more than the device can render from the spring (the gate
// clamps the rendered force to the same limit), and a saturated push cannot press the cloth
// into the fingertip with tens of newtons. The damper still follows the device's velocity:
// scaling it back too let the multirate path's global proxies trail a fast finger
// (docs/contact.md, 'The model').
void FingertipContact::set_coupling_target(cloth::ProxyNode& P, const FingerTarget& device) const {
  const Vec3 reach = device.position - P.x;
  const double ask = P.stiffness * reach.norm();
  const double scale = p_.max_force > 0.0 && ask > p_.max_force ? p_.max_force / ask : 1.0;
  P.target = P.x + scale * reach;
  P.target_velocity = device.velocity;
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
    const Vec3 series = steps_.series_force(refined_axis_[f], r.force);
    r.proxy = P.x - refined_c_[f] * series;
    tip_[f] = r.proxy;
    nearest_surface(f, s, P.x, r);
    max_pen_ = std::max(max_pen_, r.penetration);
    samples_in_contact_ += r.points;
  }
}

}  // namespace hapticloth::haptics
