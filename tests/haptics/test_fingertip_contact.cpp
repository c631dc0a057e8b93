// The fingertip sphere solved with the cloth (server/haptics/fingertip_contact): checked against
// the exact rigid-sphere-on-membrane solution, the weight of a pinched cloth, Newton's third law
// from the cloth's momentum, and the depth of any cloth point inside a fingertip.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>

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
  for (const auto& p : r.points) EXPECT_LE(std::abs(p.error()), 0.05) << p.depth;
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
  // Exact with CHOLMOD; the PCG stops at a relative residual of 1e-3 (the scenes' tolerance),
  // which leaves the cloth's momentum off by up to about 2% of the weight in a step.
  EXPECT_LE(r.third_law, (spec.solver == "pcg" ? 0.05 : 1e-6) * r.weight);
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

// Both sides of 2 mu N = m g: with a light squeeze (0.5 mm, N about 0.4 N) the cloth (m g
// 0.127 N) stays put at mu 0.2 (2 mu N about 0.16 N: 1.9 mm off) and slides through the pinch
// at mu 0.02 (8.3 mm in 3 s), beyond the 5 mm a held cloth keeps to. It does not fall: draped
// over the lower fingertip, the normal forces on its fold carry it.
TEST(FingertipContact, PinchSlipsWhenFrictionCannotCarryTheWeight) {
  const test::PinchResult held = test::pinch_handkerchief(pinch(20, 0.0005, 0.2, "cholmod", 3.0));
  const test::PinchResult slipped = test::pinch_handkerchief(pinch(20, 0.0005, 0.02, "cholmod", 3.0));
  std::printf("mu 0.2: carried %.4f N of %.4f N, centre %.1f mm off; mu 0.02: carried %.4f N, centre %.1f mm off\n",
              held.carried, held.weight, held.centre_offset * 1e3, slipped.carried, slipped.centre_offset * 1e3);
  EXPECT_LE(std::abs(held.error()), 0.02);
  EXPECT_LE(held.centre_offset, 0.005);
  EXPECT_GT(slipped.centre_offset, 0.005);
}
