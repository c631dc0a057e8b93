// The local-patch coupling's global side (server/haptics/kernel_coupling): the impact at
// contact onset.
#include <gtest/gtest.h>

#include "cloth/integrator.hpp"
#include "cloth/model.hpp"
#include "haptics/modes/kernel_coupling.hpp"
#include "support/fixtures.hpp"

using namespace hapticloth;
using haptics::Vec3;

namespace {
cloth::ClothModel drum() { return test::denim_drum(); }
cloth::ClothState start_state(const cloth::ClothModel& m) {
  cloth::ClothState s = cloth::rest_state(m);
  for (auto& x : s.x) x.head<2>() *= 1.03;
  return s;
}
}  // namespace

// Impact at contact onset (4.3.2): the fingertip and the touched cloth move on together, with
// the normal momentum conserved exactly, and a heavy fingertip drags the cloth to its speed.
TEST(KernelCoupling, ImpactTransfersMomentum) {
  const cloth::ClothModel m = drum();
  cloth::Integrator integ(m, cloth::IntegratorConfig{}, cloth::make_cholmod_solver());
  haptics::KernelCoupling kernel(m, integ, 2, 2.0 * 0.3 / 20, 0.05, 0.016, 0.01);
  cloth::ClothState s = start_state(m);
  haptics::FingerReport c;
  c.in_contact = true;
  c.contact = Vec3(0.004, 0.003, 0.0);
  c.normal = Vec3(0, 0, 1);          // towards the finger, which comes from above
  c.velocity = Vec3(0, 0, -0.2);     // m/s, moving down into the cloth
  auto momentum = [&] {
    double p = 0.0;
    for (int i = 0; i < m.num_vertices(); ++i) p += m.mass[i] * s.v[i].z();
    return p;
  };
  const double me = 0.05;
  const double p0 = momentum();
  const double given = kernel.apply_impact(c, me, s);
  const double p1 = momentum();
  EXPECT_NEAR(p1 - p0, given, 1e-15);
  EXPECT_LT(given, 0.0);  // pushed down
  // Finger momentum after: me * v_es; conservation: me * ve = me * ves + given.
  const double ves = (me * (-0.2) - given) / me;
  EXPECT_LT(ves, -0.19);   // a light cloth barely slows a 50 g fingertip
  // The touched point now moves with the finger.
  int vc = 0;
  for (int i = 0; i < m.num_vertices(); ++i)
    if ((m.rest_positions[i] - c.contact).norm() < (m.rest_positions[vc] - c.contact).norm()) vc = i;
  EXPECT_LT(s.v[vc].z(), 0.5 * ves);
}
