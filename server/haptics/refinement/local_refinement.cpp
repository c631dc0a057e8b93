#include "haptics/refinement/local_refinement.hpp"

#include <algorithm>
#include <cmath>

namespace hapticloth::haptics {

namespace {
// The child reaches this many of the touched triangle's longest edges from the contact: the
// global mesh places the dimple right beyond about one element (its nodal values of w ~ ln r
// are close to exact there), so the child's border sits where the global cloth is right.
constexpr double kReachEdges = 1.5;
// A child is re-centred once its contact has moved this fraction of its reach from where the
// child was built. The child is graded toward that point, and the compliance it measures grows
// as the contact leaves it: re-centred at a quarter of the reach, a stroke's force dips below
// the exact one before each rebuild; at a tenth it stays within the child's own discretisation
// error (docs/contact.md, 'Local refinement under the fingertips', the stroke table).
constexpr double kRecentre = 0.1;

RefineSpec spec_for(const ContactParams& c, const RefinementParams& p) {
  RefineSpec s;
  s.finest = finest_edge(p, c.radius);
  s.grading = p.grading;
  return s;
}
ChildLaw child_law(const ContactParams& c) {
  ChildLaw l;
  l.radius = c.radius;
  l.pressure_stiffness = c.pressure_stiffness;
  l.stiffening_depth = c.stiffening_depth;
  return l;
}
}  // namespace

double finest_edge(const RefinementParams& p, double radius) { return p.finest > 0.0 ? p.finest : radius / 8.0; }

double longest_rest_edge(const cloth::ClothModel& m) {
  double edge = 0.0;
  for (const auto& t : m.triangles)
    for (int k = 0; k < 3; ++k)
      edge = std::max(edge, (m.rest_positions[t[k]] - m.rest_positions[t[(k + 1) % 3]]).norm());
  return edge;
}

bool mesh_needs_refinement(const cloth::ClothModel& m, const RefinementParams& p, double radius) {
  return longest_rest_edge(m) > p.resolved * finest_edge(p, radius);
}

LocalRefinement::LocalRefinement(const cloth::ClothModel& global, const ContactParams& contact,
                                 const Vec3& gravity, const RefinementParams& p)
    : g_(global), cp_(contact), gravity_(gravity), p_(p), refiner_(global), spec_(spec_for(contact, p)) {}

std::optional<ClothPoint> LocalRefinement::touched_point(const ProxyResult& r) const {
  if (!r.valid || !r.in_contact || r.triangle < 0) return std::nullopt;
  if (refiner_.longest_edge(r.triangle) <= resolved_edge()) return std::nullopt;  // resolved
  ClothPoint at;
  at.tri = r.triangle;
  for (int k = 0; k < 3; ++k) at.b[k] = r.bary[k];
  return at;
}

void RefinementInput::take(const cloth::ClothState& s, const FingertipContact& contact, int n) {
  x.resize(s.x.size());
  std::copy(s.x.begin(), s.x.end(), x.begin());
  fingers = n;
  for (int f = 0; f < n; ++f) {
    result[f] = contact.result(f);
    proxy[f] = contact.global_proxy(f);
  }
}

void LocalRefinement::build_child(int f, const ClothPoint& at, const std::vector<Vec3>& x) {
  RefineSpec spec = spec_;
  spec.reach = std::max(kReachEdges * refiner_.longest_edge(at.tri), 2.0 * cp_.radius);
  child_[f] = std::make_unique<RefinedContact>(refiner_.refine(at, spec), g_.material, gravity_,
                                               child_law(cp_));
  child_[f]->follow(x);
  anchor_[f] = refiner_.rest_point(at);
  ++builds_;
}

void LocalRefinement::update(const RefinementInput& step) {
  const int fingers = step.fingers;
  std::array<ChildFinger, kMaxFingers> in{};
  std::array<std::optional<ClothPoint>, kMaxFingers> at{};
  for (int f = 0; f < fingers; ++f) {
    const ProxyResult& r = step.result[f];
    at[f] = touched_point(r);
    in[f].in = at[f].has_value() && r.force.dot(r.normal) > 0.0;
    in[f].centre = step.proxy[f];
    in[f].normal = r.normal;
    in[f].force = r.force.dot(r.normal);
  }
  for (int f = 0; f < fingers; ++f) {
    if (!in[f].in) {
      child_[f].reset();
      compliance_[f] = SeriesCompliance{};
      continue;
    }
    const Vec3 here = refiner_.rest_point(*at[f]);
    const double reach = std::max(kReachEdges * refiner_.longest_edge(at[f]->tri), 2.0 * cp_.radius);
    const bool fresh = !child_[f] || (here - anchor_[f]).norm() > kRecentre * reach;
    if (fresh) build_child(f, *at[f], step.x);
    else child_[f]->follow(step.x);
    // The other fingertips touching this child's cloth push on it too (a pinch).
    std::array<ChildFinger, kMaxFingers> in_child{};
    const auto& region = child_[f]->mesh().region;
    for (int g = 0; g < fingers; ++g)
      if (in[g].in && std::binary_search(region.begin(), region.end(), at[g]->tri)) in_child[g] = in[g];
    child_[f]->settle(in_child, fresh ? 4 * p_.iterations : p_.iterations);
    if (in[f].force >= p_.min_force) {
      compliance_[f].c = std::min(std::max(0.0, series_depth(*child_[f], f, in_child)) / in[f].force, p_.max_compliance);
      const Vec3& push = child_[f]->push(f);
      if (push.squaredNorm() > 0.0) compliance_[f].axis = push.normalized();
    }
  }
}

// A finger's extra depth in its child, less what is a shift of a pinch. When another fingertip
// presses the same child from the other side, the two spheres and the cloth between them move
// together: the sandwich shifting by w (the cloth's weight, carried as the difference of the two
// normal forces, moves it) puts one sphere w deeper and the other w shallower. That shift is a
// motion of the cloth, which the global mesh carries, and not a compliance in series with either
// coupling; in series with each is the sandwich's squeeze, the mean of the two depths. (Taken as
// each finger's own depth, the lower finger of a held pinch gets the compliance and the upper
// none, so the upper fingertip loses the cloth and the pinch becomes a drape: docs/contact.md,
// 'Local refinement under the fingertips'.)
double LocalRefinement::series_depth(const RefinedContact& child, int f,
                                     const std::array<ChildFinger, kMaxFingers>& in_child) const {
  const double own = child.extra_depth(f);
  for (int g = 0; g < kMaxFingers; ++g)
    if (g != f && in_child[g].in && in_child[f].normal.dot(in_child[g].normal) < -0.5)
      return 0.5 * (own + child.extra_depth(g));
  return own;
}

}  // namespace hapticloth::haptics
