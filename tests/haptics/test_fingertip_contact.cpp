// The fingertip sphere solved with the cloth (server/haptics/fingertip_contact): checked against
// the exact rigid-sphere-on-membrane solution, the weight of a pinched cloth, Newton's third law
// from the cloth's momentum, and the depth of any cloth point inside a fingertip.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numeric>
#include <tuple>

#include "cloth/integrator.hpp"
#include "cloth/mesh.hpp"
#include "cloth/model.hpp"
#include "cloth/solver.hpp"
#include "haptics/contact/fingertip_contact.hpp"
#include "support/alloc_counter.hpp"
#include "support/fixtures.hpp"
#include "support/touch_scenes.hpp"

using namespace hapticloth;

TEST(FingertipContact, DrumPressMatchesMembraneTheory) {
  test::DrumSpec spec;
  const test::DrumResult r = test::press_drum(spec);
  for (const auto& p : r.points)
    std::printf("depth %.1f mm: force %.4f N, exact %.4f N, error %+.2f%%\n", p.depth * 1e3, p.force,
                p.reference, 100.0 * p.error());
  std::printf("onset at depth %.3f mm, deepest point inside %.3f mm, %d triangles\n",
              r.onset_depth * 1e3, r.max_penetration * 1e3, r.triangles);
  std::printf("%s", r.report.to_text().c_str());
  // The reference is exact (shooting, membrane_reference.hpp). The graded disc's centre
  // elements (0.25 mm) are 1/16 to 1/28 of the contact radius (4-7 mm at 1-3 mm): a linear
  // element's error in the contact force is O((h/a)^2), under 0.4%; twice that for the coarser
  // elements toward the rim: 1%.
  for (const auto& p : r.points) EXPECT_LE(std::abs(p.error()), 0.01) << p.depth;
  EXPECT_LE(std::abs(r.onset_depth), 1e-4);
}

// A hand pushing on past the device's force limit and holding there: the coupling asks the
// cloth for no more than the device renders (Newton's third law holds through the gate's
// clamp), so the drum sits where membrane theory puts it under that force, not under the
// 20 N the spring alone would ask.
TEST(FingertipContact, SaturatedPushGivesTheClothTheRenderedForce) {
  test::DrumSpec spec;
  spec.speed = 0.02;
  spec.device_depth = 0.03;  // the coupling spring alone would ask 800 N/m x ~27 mm
  spec.max_force = 0.3;
  spec.hold = 0.2;
  const test::DrumResult r = test::press_drum(spec);
  const double theory = test::sphere_indentation(spec.drum, r.final_depth).force;
  std::printf("limit %.2f N: rendered %.4f N, proxy %.3f mm deep, membrane theory there %.4f N\n",
              spec.max_force, r.final_force, r.final_depth * 1e3, theory);
  EXPECT_NEAR(r.final_force, spec.max_force, 0.01 * spec.max_force);
  EXPECT_NEAR(theory, spec.max_force, 0.02 * spec.max_force);
  EXPECT_LE(r.max_penetration, 0.5e-3);
}

// A free cloth pinched from either side and held still carries exactly its weight, its centre
// stays at the pinch, no cloth point gets 0.5 mm into a fingertip, and the force the cloth got
// (from its momentum) is minus the rendered force on every step. Two corners of the range;
// hapticloth-bench fidelity runs meshes of 20-40 quads, squeezes 1-4 mm, friction 0.6-1.0 and
// both solvers (BENCHMARKS.md).
class Handkerchief : public ::testing::TestWithParam<test::PinchSpec> {};

TEST_P(Handkerchief, CarriesItsWeight) {
  const test::PinchSpec spec = GetParam();
  const test::PinchResult r = test::pinch_handkerchief(spec);
  std::printf("weight %.4f N carried %.4f N (%+.2f%%), centre %.2f mm off, deepest %.3f mm, third law %.2e N\n",
              r.weight, r.carried, 100 * r.error(), r.centre_offset * 1e3, r.max_penetration * 1e3,
              r.third_law);
  std::printf("%s", r.report.to_text().c_str());
  EXPECT_LE(std::abs(r.error()), 0.02);
  EXPECT_LE(r.centre_offset, 0.005);
  EXPECT_LE(r.max_penetration, 0.0005);
  // Exact with CHOLMOD. The PCG stops at |r| <= tol |b| (tol 1e-3, the scenes'), and the
  // cloth's momentum misses the rendered force by the residual's net sum over the rows, / h
  // (the elastic forces sum to zero). That sum is about |r| (the rows' residuals have mixed
  // signs; at worst it is sqrt(n) |r|), and |b| / h is dominated by the two coupling springs'
  // forces, k s each: so tol sqrt(2) k s, 4.5 mN at the 4 mm squeeze (3.6% of the weight).
  const double coupling = test::touch_session(spec.friction).finger.stiffness * spec.squeeze;
  EXPECT_LE(r.third_law, spec.solver == "pcg" ? test::touch_pcg().tolerance * std::sqrt(2.0) * coupling
                                              : 1e-6 * r.weight);
  // With PCG the 1 ms steps revise their contacts on local settles and end at a whole solve
  // (Integrator::revise_contacts); without that last solve the third law above was 52 mN off.
  // CHOLMOD re-solves whole. (The report printed above gives the counts.)
  if (spec.solver == "pcg") {
    EXPECT_GT(r.report.contact_settles, 0u);
    EXPECT_GT(r.report.contact_confirmations, 0u);
  } else {
    EXPECT_EQ(r.report.contact_settles, 0u);
  }
}

test::PinchSpec pinch(int quads, double squeeze, double mu, const char* solver, double hold = 6.0) {
  test::PinchSpec s;
  s.quads = quads;
  s.squeeze = squeeze;
  s.friction = mu;
  s.solver = solver;
  s.hold = hold;
  return s;
}

INSTANTIATE_TEST_SUITE_P(MeshSqueezeFrictionSolver, Handkerchief,
                         ::testing::Values(pinch(20, 0.001, 0.6, "cholmod"), pinch(40, 0.004, 1.0, "pcg")));

// Both sides of 2 mu N = m g, for a cloth that only friction can hold: the square hangs from a
// pinch between two fingertips pressing on its faces 2 cm below its top edge (1 mm squeeze: N
// about k s = 0.8 N; m g = 0.127 N). At mu 0.2 (2 mu N about 0.32 N) the pinch carries the weight
// and the cloth stays. At mu 0.05 (2 mu N about 0.08 N, under m g) it slides down through the
// pinch and falls away: over the last second the fingers carry well under its weight (nothing,
// once it has gone), neither touches it at the end, and it has fallen far below the pinch.
TEST(FingertipContact, PinchSlipsWhenFrictionCannotCarryTheWeight) {
  test::PinchSpec spec = pinch(20, 0.001, 0.2, "cholmod", 1.5);
  spec.from_the_sides = true;
  const test::PinchResult held = test::pinch_handkerchief(spec);
  spec.friction = 0.05;
  const test::PinchResult slipped = test::pinch_handkerchief(spec);
  std::printf("mu 0.2: carried %.4f N of %.4f N, pinched point %.1f mm off; mu 0.05: carried %.4f N, "
              "pinched point %.0f mm lower, touching at the end: %d\n",
              held.carried, held.weight, held.centre_offset * 1e3, slipped.carried, slipped.centre_drop * 1e3,
              slipped.in_contact_at_end);
  EXPECT_LE(std::abs(held.error()), 0.02);
  EXPECT_LE(held.centre_offset, 0.005);
  EXPECT_TRUE(held.in_contact_at_end);
  EXPECT_LT(slipped.carried, 0.5 * slipped.weight);
  EXPECT_FALSE(slipped.in_contact_at_end);
  EXPECT_GT(slipped.centre_drop, 0.1);  // the pinch 2 cm below the top: well past the fingertips
}

// The pressure law against a rigid sphere on a rigid plane (every vertex pinned): the proxy
// settles where the force it renders equals the law integrated over the contact disc. At
// radius r on the plane the depth is u = R - sqrt(c^2 + r^2) (c = R - d, the centre's height),
// so r dr = -(R - u) du, and the pressure acts along the sphere's normal, whose vertical share
// is c / (R - u):
//   F(d) = 2 pi c int_0^d p(u) du = 2 pi (R - d) kappa (d^2 / 2 + d^3 / (3 d_s)).
// Light presses follow the linear law kappa d; at the device's 8 N the stiffening holds the
// sphere shallower than the linear law would (0.32 mm).
TEST(FingertipContact, PressOnARigidPlaneFollowsThePressureLaw) {
  cloth::GridSpec g;
  g.width = g.height = 0.03;
  g.nx = g.ny = 30;
  g.origin = {-0.015, -0.015, 0.0};
  const cloth::Mesh mesh = cloth::make_grid(g);
  std::vector<int> pins(mesh.positions.size());
  std::iota(pins.begin(), pins.end(), 0);
  const cloth::ClothModel m = cloth::build_model(mesh, test::denim(), pins);
  cloth::IntegratorConfig cfg;
  cfg.gravity.setZero();
  cfg.proxies = 2;  // the second finger has no device sample: it touches nothing
  cloth::Integrator integ(m, cfg, cloth::make_cholmod_solver());
  haptics::ContactParams p;
  p.friction = 0.0;
  p.sample_spacing = 0.2e-3;  // a fine quadrature of the 1.5-2.5 mm contact disc
  haptics::FingertipContact tips(m, m.triangles, 2, p, integ);
  cloth::ClothState s = cloth::rest_state(m);
  const double R = p.radius, kappa = p.pressure_stiffness, ds = p.stiffening_depth;
  auto law = [&](double d) { return 2.0 * M_PI * (R - d) * kappa * (d * d / 2 + d * d * d / (3 * ds)); };
  double last_depth = 0.0;
  for (const double ask : {0.5, 2.0, 8.0}) {
    std::array<haptics::FingerTarget, haptics::kMaxFingers> in{};
    in[0] = {true, haptics::Vec3(0.0, 0.0, R - ask / p.coupling_stiffness), haptics::Vec3::Zero()};
    for (int step = 0; step < 20; ++step) {
      tips.begin_step(s, in, cfg.dt);
      ASSERT_EQ(integ.step(s), cloth::StepOutcome::Accepted);
      tips.end_step(s);
    }
    const haptics::ProxyResult& r = tips.result(0);
    const double depth = R - r.proxy.z(), force = r.force.z();
    const double linear_depth = std::sqrt(force / (M_PI * (R - depth) * kappa));
    std::printf("coupling asks %.1f N: renders %.4f N at %.4f mm deep; the law there %.4f N (%+.2f%%); "
                "the linear law would sit %.4f mm deep\n",
                ask, force, depth * 1e3, law(depth), 100.0 * (force / law(depth) - 1.0), linear_depth * 1e3);
    EXPECT_NEAR(force, law(depth), 0.005 * force);
    EXPECT_NEAR(r.penetration, depth, 1e-6);  // the plane is the deepest point, at the pole
    EXPECT_GT(depth, last_depth);
    if (ask > 4.0) {
      EXPECT_LT(depth, 0.8 * linear_depth);
    }
    last_depth = depth;
  }
}

// A fingertip striking a drum at 2 m/s, obliquely, and dragging through it at the device's 8 N
// limit: every step's active set converges before the revision cap (released contacts keep
// their friction state when they come back, and the line search of
// Integrator::revise_contacts), no cloth point gets 0.5 mm inside the sphere, and every step
// ends at a solve: the massless proxy is in force balance, its coupling force (what the device
// renders) equal to the contact forces the cloth got (Newton's third law, tick by tick). After
// the first step (which sizes the solver's buffers) the contact steps allocate nothing: the
// broad phase's walk, the contact lists and the re-solves' copies live in memory reserved at
// construction.
// The 0.3 m denim drum (20 x 20 quads) solved with CHOLMOD, two fingertips with friction 0.6.
struct DrumAndTwoTips {
  explicit DrumAndTwoTips(double max_force = 0.0) : p(params(max_force)) {}  // 0: no limit
  static haptics::ContactParams params(double max_force) {
    haptics::ContactParams c;
    c.friction = 0.6;
    c.max_force = max_force;
    return c;
  }
  static cloth::IntegratorConfig two_proxies() {
    cloth::IntegratorConfig c;
    c.proxies = 2;
    return c;
  }
  const cloth::ClothModel m = test::denim_drum(20, 0.3);
  const cloth::IntegratorConfig cfg = two_proxies();
  cloth::Integrator integ{m, cfg, cloth::make_cholmod_solver()};
  const haptics::ContactParams p;
  haptics::FingertipContact tips{m, m.triangles, 2, p, integ};
};

TEST(FingertipContact, FastStrikeConvergesWithTheClothOutside) {
  DrumAndTwoTips rig(8.0);
  const cloth::ClothModel& m = rig.m;
  const cloth::IntegratorConfig& cfg = rig.cfg;
  cloth::Integrator& integ = rig.integ;
  const haptics::ContactParams& p = rig.p;
  haptics::FingertipContact& tips = rig.tips;
  cloth::ClothState s = cloth::rest_state(m);
  const haptics::Vec3 v(1.2, 0.4, -1.55);  // m/s, 2 m/s
  haptics::Vec3 at(-0.06, -0.02, 0.03);
  double deepest = 0.0, imbalance = 0.0;
  int capped = 0, touching = 0;
  std::uint64_t allocations = 0;
  for (int step = 0; step < 60; ++step) {
    const test::AllocationGuard guard;
    at += cfg.dt * v;
    std::array<haptics::FingerTarget, haptics::kMaxFingers> in{};
    in[0] = {true, at, v};
    const auto before = integ.events().contact_revisions;
    const haptics::Vec3 x0 = integ.proxies()[0].x;
    tips.begin_step(s, in, cfg.dt);
    ASSERT_EQ(integ.step(s), cloth::StepOutcome::Accepted);
    tips.end_step(s);
    const haptics::ProxyResult& r = tips.result(0);
    capped += integ.events().contact_revisions - before >= static_cast<std::uint64_t>(cfg.max_contact_revisions);
    touching += r.in_contact;
    deepest = std::max(deepest, r.penetration);
    if (step > 0) allocations += guard.count();  // the first step sizes the solver's buffers
    if (step > 0) {  // the proxy starts at the fingertip on the first step
      const haptics::Vec3 coupling = p.coupling_stiffness * (r.target - r.proxy) +
                                     p.coupling_damping * (r.target_velocity - (r.proxy - x0) / cfg.dt);
      imbalance = std::max(imbalance, (coupling + r.force).norm());
    }
  }
  std::printf("%d steps in contact, %d at the revision cap, deepest cloth point %.3f mm inside, "
              "%llu re-solves, largest proxy imbalance %.2e N, %llu allocations after the first step\n",
              touching, capped, deepest * 1e3, static_cast<unsigned long long>(integ.events().contact_revisions),
              imbalance, static_cast<unsigned long long>(allocations));
  EXPECT_GT(touching, 20);
  EXPECT_EQ(capped, 0);
  EXPECT_LT(deepest, 0.5e-3);
  EXPECT_LT(imbalance, 1e-6);
  EXPECT_EQ(allocations, 0u);  // the sim thread's hot path
}

// A re-solve that took no iteration hands the contacts the candidate they saw last; the free
// revisions (those that may release contacts or let a sliding contact stick again) end there,
// since on the same candidate they could only repeat themselves. The candidate here: the cloth
// pressed 1 mm by a fingertip, then moved away from its centre to 1.5 times the distance
// (along each contact's normal, so no friction acts). Seen fresh, every contact is released;
// seen again after a re-solve that took no iteration, nothing changes.
TEST(FingertipContact, TheSameCandidateEndsTheFreeRevisions) {
  DrumAndTwoTips rig;  // the second finger absent
  cloth::Integrator& integ = rig.integ;
  const haptics::ContactParams& p = rig.p;
  haptics::FingertipContact& tips = rig.tips;
  const cloth::ClothState s = cloth::rest_state(rig.m);
  const haptics::Vec3 centre(0.0, 0.0, p.radius - 1e-3);
  std::vector<haptics::Vec3> pulled_off = s.x;
  for (auto& x : pulled_off) x = centre + 1.5 * (x - centre);
  auto revise = [&](bool same_candidate) {
    std::array<haptics::FingerTarget, haptics::kMaxFingers> in{};
    in[0] = {true, centre, haptics::Vec3::Zero()};
    tips.begin_step(s, in, 1e-3);
    const size_t touching = integ.point_springs().size();
    const bool changed = tips.revise(pulled_off, integ.proxies(), false, same_candidate);
    return std::make_tuple(touching, changed, integ.point_springs().size());
  };
  const auto [touching, released, left] = revise(false);
  EXPECT_GT(touching, 10u);
  EXPECT_TRUE(released);
  EXPECT_EQ(left, 0u);
  const auto [touching_again, changed, kept] = revise(true);
  EXPECT_EQ(touching_again, touching);
  EXPECT_FALSE(changed);
  EXPECT_EQ(kept, touching);
}

// With a refined compliance c in series (local refinement, direct coupling), the coupling is
// the chain through the fingertip: k1 = k + b/h across the contact's axis, 1 / (1/k1 + c) along
// it. A device far across the axis (a fast finger, or a hand past the limit) must not make that
// chain ask the cloth for more than the device renders: the target is pulled back until
// |K (target - proxy)| is the limit. (It was pulled back with the soft isotropic spring alone,
// and the stiffer k1 across then asked 180 N of an 8 N device; a random two-finger stroke's
// step blew up on it.)
TEST(FingertipContact, ChainThroughTheFingertipAsksNoMoreThanTheLimit) {
  DrumAndTwoTips rig(8.0);
  cloth::Integrator& integ = rig.integ;
  haptics::FingertipContact& tips = rig.tips;
  cloth::ClothState s = cloth::rest_state(rig.m);
  const double dt = rig.cfg.dt;
  tips.set_refined_compliance(0, haptics::SeriesCompliance{.c = 0.005});
  std::array<haptics::FingerTarget, haptics::kMaxFingers> in{};
  double largest_ask = 0.0;
  bool chained = false;
  for (int step = 0; step < 120; ++step) {
    // 2 mm into the drum's centre by step 60, then the device 0.1 m across, then back.
    const double depth = std::min(step, 60) * 2e-3 / 60;
    const haptics::Vec3 across = step >= 80 && step < 100 ? haptics::Vec3(0.1, 0.0, 0.0) : haptics::Vec3::Zero();
    in[0] = {true, haptics::Vec3(0.0, 0.0, rig.p.radius - depth) + across, haptics::Vec3::Zero()};
    tips.begin_step(s, in, dt);
    const cloth::ProxyNode& P = integ.proxies()[0];
    chained = chained || P.axis_stiffness > 0.0;
    largest_ask = std::max(largest_ask, (P.stiffness_matrix() * (P.target - P.x)).norm());
    ASSERT_EQ(integ.step(s), cloth::StepOutcome::Accepted) << "step " << step;
    tips.end_step(s);
  }
  std::printf("largest force the coupling asked: %.3f N (limit 8 N)\n", largest_ask);
  EXPECT_TRUE(chained);                       // the chain through the fingertip was on
  EXPECT_GT(largest_ask, 7.9);                // the device across reached the limit...
  EXPECT_LE(largest_ask, 8.0 * (1.0 + 1e-12));  // ...and no further
}
