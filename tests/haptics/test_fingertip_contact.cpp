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
  if (const char* e = std::getenv("DRUM_EDGE")) spec.centre_edge = std::atof(e);
  if (const char* e = std::getenv("SOLVER")) spec.solver = e;
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

TEST(FingertipContact, PinchedHandkerchiefCarriesItsWeight) {
  test::PinchSpec spec;
  if (const char* e = std::getenv("SOLVER")) spec.solver = e;
  if (const char* e = std::getenv("QUADS")) spec.quads = std::atoi(e);
  if (const char* e = std::getenv("SQUEEZE")) spec.squeeze = std::atof(e);
  if (const char* e = std::getenv("MU")) spec.friction = std::atof(e);
  const test::PinchResult r = test::pinch_handkerchief(spec);
  std::printf("weight %.4f N carried %.4f N (%+.2f%%), centre %.2f mm off, deepest %.3f mm, third law %.2e N\n",
              r.weight, r.carried, 100 * r.error(), r.centre_offset * 1e3, r.max_penetration * 1e3,
              r.third_law);
  std::printf("%s", r.report.to_text().c_str());
  EXPECT_LE(std::abs(r.error()), 0.02);
  EXPECT_LE(r.centre_offset, 0.005);
  EXPECT_LE(r.max_penetration, 0.0005);
}
