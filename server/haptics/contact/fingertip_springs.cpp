// The fingertip's contact springs (fingertip_contact.hpp): their stiffness from the pressure
// law, Coulomb friction, and the active set revised between the step's re-solves.
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

// A sample that would pull harder than this (N per m^2 of its area per kappa, i.e. metres of
// negative depth) is dropped.
constexpr double kPullDepth = 1e-6;  // m

// Re-solves of a step that may release contacts (see revise()).
constexpr int kFreeRevisions = 12;
}  // namespace

void FingertipContact::linearize_pressure(Sample& q) const {
  const double kw = p_.pressure_stiffness * q.w, d = std::max(q.depth0, 0.0);
  q.kn = steps_.pressure_stiffness(kw, d, p_.stiffening_depth);
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
  sp.kn = steps_.line_search_stiffness(q.kn);
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
  } else if (steps_.slides_against_slip()) {
    // A slide scaled to nothing while its normal force was (a contact whose end state pulled
    // at an earlier re-solve) has no direction left: kinetic friction opposes the point's slip
    // over the sphere, where the step's rules say so (ContactStepRules::slides_against_slip).
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
// friction, past the Coulomb bound (BENCHMARKS.md, 'Stability stress map'). Returns true if any did.
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
// reserved at construction: std::inplace_merge allocates one on every call, and nothing may be
// allocated on the step (docs/contact.md, 'The model').
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
  // inside. Twelve free revisions are enough for the multirate path's long steps: fewer, or
  // freezing friction too, let the cloth end inside a fingertip in its pinch and the friction
  // of its stroke chatter (docs/contact.md, 'The model').
  // A short step (direct coupling) also defers its late slide-to-stick switches: after the free
  // revisions a contact that slides stays sliding to the next step, 1 ms later (its magnitude
  // still follows its normal force). Otherwise contacts at the cone's edge flip between stick
  // and slide until the revision cap, and the step ends before the samples that the last solve
  // pushed inside are added. A long global step of the multirate path holds its friction state
  // for the whole step and keeps revising it (deferring there let a pinch carry less than the
  // weight: docs/contact.md, 'The model'). The integrator's line search keeps whole re-solves
  // from overshooting (Integrator::revise_contacts; a step revised on local settles has none);
  // contacts released earlier in the step come back with their state (add_contacts,
  // restore_touching).
  // A re-solve that left the solution as it was (a PCG re-solve that took no iteration) hands
  // back the same candidate: on it, a contact whose friction the solver cannot resolve (a change
  // under its tolerance) would switch between sticking and sliding until the free revisions ran
  // out, each switch a re-solve that again takes no iteration (docs/performance.md, 'Re-solves
  // that take no iteration, and what the release's steps are made of'). So the free revisions
  // end there.
  if (same_candidate) revisions_ = std::max(revisions_, kFreeRevisions);
  const bool settle = revisions_ < kFreeRevisions;
  const bool defer = !settle && steps_.defers_late_sticking();
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

}  // namespace hapticloth::haptics
