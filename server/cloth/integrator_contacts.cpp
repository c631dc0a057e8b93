// The Integrator's active set of contact springs: re-solves while the set changes, settles, and
// the line search that ends a cycling set.
#include "cloth/integrator.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <numeric>
#include <stdexcept>
#include <string>

namespace hapticloth::cloth {

namespace {

// Re-solves of a step taken whole before the active set's line search (line_search_contacts)
// starts: a set that one re-solve settles, as in a slow stroke, is left to it. Searching from the
// first revises the stroke's friction at the line search's points and takes its Coulomb error
// per contact further from the bound (docs/contact.md, 'The model'), while the cycling it is
// for takes many re-solves.
constexpr int kPlainRevisions = 1;
using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

}  // namespace

// Active set: a contact that would pull or a point that would pass into a fingertip changes the
// point springs; the step is solved again with them (warm-started from the last solution),
// telling the solver which block rows the change touched, and the re-solve is taken as far as
// the line search allows. The step ends at a solve (the last re-solve taken whole), so the
// massless proxies are in exact force balance: what the device renders is what the cloth got.
// A short step whose solver can settle its contacts' rows alone (LinearSolver::
// settle_changed: the proxies and the vertices they hold, the rest of the cloth held) revises
// on those settles instead, and once the contacts ask for nothing more, solves the whole cloth
// from there and asks them again (confirm_settled). A whole re-solve of a pinch's release
// costs about as many iterations as the step's first solve, spent on the cloth far from the
// fingers, while the contacts' decisions are made on the rows they hold (docs/performance.md,
// "Contacts revised on local settles"). Such a step has no line search: a settle moves only
// those rows, so it cannot throw the whole cloth clear of a fingertip as a whole re-solve can,
// and the cycling the search stops is left to the free revisions' bound
// (FingertipContact::revise); the random two-finger runs stay within the allowed depth
// (BENCHMARKS.md, 'Stability stress map').
bool Integrator::revise_contacts(const ClothState& s, double h) {
  released_.clear();
  bool cut = false;  // dv_ is the line search's point short of the re-solve dv_full_
  bool same = false;  // the last re-solve left dv_ as it was (it took no iteration)
  bool unconfirmed = false;  // dv_ is a settle's: the cloth away from the contacts not solved since
  // Direct coupling's short steps revise their contacts on local settles, confirmed by a whole
  // solve; the multirate path's long ones solve whole.
  const bool settles = cfg_.contact_steps == ContactSteps::Short && solver_->settles_locally();
  for (int rev = 0; contacts_ && rev < cfg_.max_contact_revisions; ++rev) {
    springs_solved_.assign(springs_.begin(), springs_.end());
    if (!contacts_->revise(xn_, proxies_, cut, same)) {
      if (!unconfirmed) break;
      if (!confirm_settled(s, h, same)) return false;
      unconfirmed = cut = false;
      continue;  // the contacts asked again, on the whole solve
    }
    ++events_.contact_revisions;
    dv_from_ = dv_;
    const auto t3 = Clock::now();
    add_springs(s, h, springs_solved_, -1.0);
    add_springs(s, h, springs_, 1.0);
    springs_in_matrix_.assign(springs_.begin(), springs_.end());
    spring_rows_.clear();
    mark_spring_rows(springs_solved_);
    mark_spring_rows(springs_);
    for (int row : spring_rows_) spring_row_marked_[row] = 0;
    // The last revision a step may make is solved whole: the step ends at a solve.
    const bool settle = settles && rev + 1 < cfg_.max_contact_revisions;
    const int rows = static_cast<int>(spring_rows_.size());
    const SolveStatus st = settle ? solver_->settle_changed(A_, spring_rows_.data(), rows, rhs_.data(), dv_.data())
                                  : solver_->solve_changed(A_, spring_rows_.data(), rows, rhs_.data(), dv_.data());
    events_.contact_settles += settle;
    if (!account_resolve(st, t3, same)) return false;
    unconfirmed = settle;
    // A settle is taken whole (the line search's quadratic holds for a whole solve only).
    cut = !settle && rev >= kPlainRevisions && rev + 1 < cfg_.max_contact_revisions && line_search_contacts(s, h);
    candidate_state(s, h);
  }
  if (unconfirmed && !confirm_settled(s, h, same)) return false;
  if (cut) {
    dv_ = dv_full_;
    candidate_state(s, h);
  }
  return true;
}

// The whole solve after settled revisions: from the settled dv_, every row of the cloth, with
// the matrix of the last settle (its rows are reloaded); the contacts are then asked on it.
bool Integrator::confirm_settled(const ClothState& s, double h, bool& same) {
  ++events_.contact_confirmations;
  dv_from_ = dv_;
  const auto t = Clock::now();
  if (!account_resolve(solver_->resolve(A_, rhs_.data(), dv_.data()), t, same)) return false;
  candidate_state(s, h);
  return true;
}

// A re-solve's accounting (begun at t0, from dv_from_): its iterations and time, whether it
// left dv_ as it was (`same`: whatever the solver; a PCG guess already within its tolerance),
// and dv_full_; false if it failed (resolved()).
bool Integrator::account_resolve(SolveStatus st, Clock::time_point t0, bool& same) {
  solver_synced_ = st == SolveStatus::Ok;
  timing_.iterations += solver_->iterations();
  same = dv_ == dv_from_;
  timing_.solve_ms += ms_since(t0);
  if (!resolved(st)) return false;
  dv_full_ = dv_;
  return true;
}

// False, with the cause counted and the warm start cleared, if a solve failed or left dv_ not
// finite.
bool Integrator::resolved(SolveStatus st) {
  if (st == SolveStatus::Ok && dv_.allFinite()) return true;
  switch (st) {
    case SolveStatus::Ok: ++events_.non_finite; break;
    case SolveStatus::NotConverged: ++events_.solver_not_converged; break;
    case SolveStatus::NotPositiveDefinite: ++events_.not_positive_definite; break;
    default: ++events_.solver_error; break;
  }
  dv_.setZero();
  dv_prev_.setZero();
  return false;
}

// The active set as a globalized semismooth Newton method. With backward Euler (alpha 1) the
// step minimizes the incremental potential Phi: the quadratic of eq. 9 with every contact's
// penalty one-sided, 1/2 kn max(0, depth)^2 (convex). A re-solve minimizes the quadratic that
// takes the new set's contacts as two-sided; taken whole, it can overshoot: an impact's
// contacts push the cloth clear, all are released, the cloth falls back in, all are added...
// (the random two-finger runs of `hapticloth-bench stability` cycled so until the revision cap,
// and the set frozen there left contacts pulling the cloth into the fingertip: docs/contact.md,
// 'The model'). So
// the step goes from the point the set was decided at (dv_from_) towards the re-solve (dv_)
// only as far as Phi decreases: the root of dPhi/dt on [0, 1], piecewise linear and
// non-decreasing in t. The quadratic part is (t - 1) delta^T A delta (the re-solve's gradient
// is zero at t = 1); a contact of the new set adds -kn min(0, depth) dd (its linear spring
// pulls where the one-sided one does not); a released contact kn max(0, depth) dd.
// Friction is held as the new set has it. At alpha < 1 the quadratic is not Phi, and the re-solve
// is taken whole; so is it when no spring is one-sided (a contact owner may leave kn 0: the
// fingertips do in the multirate path's long steps). Returns true if the step was cut short of
// the re-solve.
bool Integrator::line_search_contacts(const ClothState& s, double h) {
  const auto one_sided = [](const PointSpring& sp) { return sp.kn > 0.0; };
  if (alpha_ != 1.0 || (std::none_of(springs_.begin(), springs_.end(), one_sided) &&
                        std::none_of(springs_solved_.begin(), springs_solved_.end(), one_sided)))
    return false;
  // The contacts released by this step's re-solves so far (springs_solved_ less springs_,
  // added to those released before) stay in Phi: a re-solve without them must not push their
  // points back inside unseen, only to add them again two re-solves later.
  auto before = [](const PointSpring& a, const PointSpring& b) {
    return a.proxy < b.proxy || (a.proxy == b.proxy && a.key < b.key);
  };
  auto in_set = [&](const PointSpring& sp) {
    return std::binary_search(springs_.begin(), springs_.end(), sp, before);
  };
  for (const PointSpring& sp : springs_solved_)
    if (sp.kn > 0.0 && !in_set(sp)) released_.push_back(sp);
  std::sort(released_.begin(), released_.end(), before);
  released_.erase(std::unique(released_.begin(), released_.end(),
                              [](const PointSpring& a, const PointSpring& b) { return a.proxy == b.proxy && a.key == b.key; }),
                  released_.end());
  released_.erase(std::remove_if(released_.begin(), released_.end(), in_set), released_.end());
  ls_terms_.clear();
  auto add_term = [&](const PointSpring& sp, bool in) {
    const double d0 = spring_depth(sp, s, h, dv_from_), d1 = spring_depth(sp, s, h, dv_);
    ls_terms_.push_back({sp.kn, d0, d1 - d0, in});
  };
  for (const PointSpring& sp : springs_)
    if (sp.kn > 0.0) add_term(sp, true);
  for (const PointSpring& sp : released_) add_term(sp, false);
  auto contacts_slope = [&](double t) {
    double g = 0.0;
    for (const DepthTerm& c : ls_terms_) {
      const double d = c.d + t * c.dd;
      g += c.in_set ? -c.kn * std::min(0.0, d) * c.dd : c.kn * std::max(0.0, d) * c.dd;
    }
    return g;
  };
  // At t = 1 the quadratic part is zero: most re-solves are taken whole without the product.
  if (contacts_slope(1.0) <= 0.0) return false;
  delta_ = dv_ - dv_from_;
  A_.multiply(delta_.data(), a_delta_.data());
  const double dad = delta_.dot(a_delta_);
  if (!(dad > 0.0)) return false;
  auto slope = [&](double t) { return (t - 1.0) * dad + contacts_slope(t); };
  if (slope(0.0) >= 0.0) return false;  // no descent along it: the whole step
  double lo = 0.0, hi = 1.0;
  for (int it = 0; it < 30; ++it) {
    const double mid = 0.5 * (lo + hi);
    (slope(mid) < 0.0 ? lo : hi) = mid;
  }
  ++events_.contact_line_cuts;
  dv_ = dv_from_ + hi * delta_;
  return true;
}

}  // namespace hapticloth::cloth
