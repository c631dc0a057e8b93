// The multirate path's response model (server/haptics/response_contact.cpp) held to the
// physics of the direct coupling: at a 20 ms global step the drum press stays within 10% of
// membrane theory and a pinch carries the handkerchief's weight within 5%.
#include <gtest/gtest.h>

#include <cstdio>

#include "support/touch_scenes.hpp"

using namespace hapticloth;

TEST(ResponseContact, DrumPressAt20msMatchesMembraneTheory) {
  test::DrumSpec spec;
  spec.centre_edge = 1e-3;
  spec.global_dt = 0.02;
  const test::DrumResult r = test::press_drum(spec);
  for (const auto& p : r.points) {
    std::printf("response, 20 ms: %.0f mm: %.4f N vs %.4f N (%+.2f%%)\n", p.depth * 1e3, p.force,
                p.reference, 100 * p.error());
    EXPECT_NEAR(p.error(), 0.0, 0.10) << p.depth;
  }
  std::printf("onset %.3f mm, deepest cloth point %.3f mm, %llu steps\n", r.onset_depth * 1e3,
              r.max_penetration * 1e3, static_cast<unsigned long long>(r.report.sim_steps));
}

TEST(ResponseContact, PinchAt20msCarriesTheWeight) {
  test::PinchSpec spec;
  spec.quads = 20;
  spec.solver = "pcg";
  spec.global_dt = 0.02;
  const test::PinchResult r = test::pinch_handkerchief(spec);
  std::printf("response, 20 ms: carried %.5f N of m g %.5f N (%+.2f%%), centre %.2f mm off, "
              "deepest %.3f mm\n", r.carried, r.weight, 100 * r.error(), r.centre_offset * 1e3,
              r.max_penetration * 1e3);
  EXPECT_NEAR(r.error(), 0.0, 0.05);
  EXPECT_LT(r.centre_offset, 0.005);
}
