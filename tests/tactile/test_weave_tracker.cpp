// Where on the fabric a fingertip is (server/tactile/weave_tracker): the material map of a
// deformed triangle, the slip integrated between steps, the pull towards the step's anchor
// bounded, and a fingertip that moves with the cloth staying where it is.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <Eigen/Geometry>

#include "tactile/weave_tracker.hpp"

using namespace hapticloth;
using tactile::Vec3;
using tactile::WeaveAnchor;
using tactile::WeaveTracker;
using Uv = Eigen::Vector2d;

namespace {
constexpr double kDt = 1e-3;

// A cloth point's anchor on a flat cloth stretched by `stretch` along x, moving at `cloth_v`.
WeaveAnchor flat_anchor(double u, double v, double stretch, const Vec3& cloth_v, double time) {
  WeaveAnchor a;
  a.valid = true;
  a.time = time;
  a.uv = Uv(u, v);
  a.map = tactile::weave_map(Vec3(0, 0, 0), Vec3(stretch * 0.01, 0, 0), Vec3(0, 0.01, 0), Uv(0, 0), Uv(0.01, 0),
                             Uv(0, 0.01));
  a.surface_velocity = cloth_v;
  return a;
}
}  // namespace

// A triangle stretched 10% along x, sheared and turned in space: a displacement along its
// stretched edge covers 1/1.1 of the material, and the normal none.
TEST(WeaveTracker, MapOfADeformedTriangleGivesMaterialDisplacement) {
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  const Vec3 x0(0.1, 0.2, 0.3);
  const Vec3 e1 = R * Vec3(0.011, 0.0, 0.0), e2 = R * Vec3(0.002, 0.01, 0.0);  // sheared
  const tactile::WeaveMap M = tactile::weave_map(x0, x0 + e1, x0 + e2, Uv(1, 2), Uv(1.01, 2), Uv(1, 2.01));
  // The corners map back to their material points, and the normal to nothing.
  EXPECT_NEAR((M * e1 - Uv(0.01, 0)).norm(), 0.0, 1e-12);
  EXPECT_NEAR((M * e2 - Uv(0, 0.01)).norm(), 0.0, 1e-12);
  EXPECT_NEAR((M * (R * Vec3::UnitZ())).norm(), 0.0, 1e-12);
  EXPECT_NEAR((M * (R * Vec3(1e-3, 0, 0))).x(), 1e-3 / 1.1, 1e-12);
  // A degenerate triangle maps to zero, not to infinities.
  EXPECT_TRUE(tactile::weave_map(x0, x0 + e1, x0 + 2 * e1, Uv(0, 0), Uv(1, 0), Uv(0, 1)).isZero(0.0));
}

// Sliding at 40 mm/s over a cloth stretched 3%: the tracked point moves at 40 / 1.03 mm/s over
// the fabric, from the first anchor on.
TEST(WeaveTracker, IntegratesTheSlipOverTheFabric) {
  WeaveTracker t;
  const Vec3 tip(0.04, 0, 0);
  Uv uv = t.track(flat_anchor(0.005, 0.002, 1.03, Vec3::Zero(), 0.0), tip, 0.0, kDt);
  EXPECT_EQ(uv, Uv(0.005, 0.002));
  for (int k = 1; k <= 500; ++k) {
    const double now = k * kDt;
    // the steps' anchors where the slip says (every tick, as with direct coupling)
    uv = t.track(flat_anchor(0.005 + 0.04 / 1.03 * now, 0.002, 1.03, Vec3::Zero(), now), tip, now, kDt);
  }
  EXPECT_NEAR(uv.x(), 0.005 + 0.04 / 1.03 * 0.5, 1e-9);
  EXPECT_NEAR(uv.y(), 0.002, 1e-12);
}

// The anchor wobbles by +-150 um a tick (a coarse mesh's ray-cast): the tracked point does not.
// Each tick's advance stays within kMaxPull of the slip's, and the tracker stays within a few
// tens of micrometres of where the fingertip is on average.
TEST(WeaveTracker, AveragesTheAnchorsWobbleOut) {
  WeaveTracker t;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> wobble(-150e-6, 150e-6);
  const Vec3 tip(0.05, 0, 0);
  Uv last = t.track(flat_anchor(0.0, 0.0, 1.0, Vec3::Zero(), 0.0), tip, 0.0, kDt);
  double worst_step = 0.0, worst_off = 0.0;
  for (int k = 1; k <= 1000; ++k) {
    const double now = k * kDt, truth = 0.05 * now;
    const Uv uv = t.track(flat_anchor(truth + wobble(rng), 0.0, 1.0, Vec3::Zero(), now), tip, now, kDt);
    worst_step = std::max(worst_step, std::abs((uv.x() - last.x()) / (0.05 * kDt) - 1.0));
    if (k > 100) worst_off = std::max(worst_off, std::abs(uv.x() - truth));
    last = uv;
  }
  std::printf("advance off the slip's by %.1f%% at most; %.1f um from the truth at most\n", 100 * worst_step,
              1e6 * worst_off);
  EXPECT_LE(worst_step, WeaveTracker::kMaxPull + 1e-9);
  EXPECT_LT(worst_off, 60e-6);
}

// A fingertip that moves with the cloth (a drag, a pinch carrying it) stays on the same point
// of the fabric: no texture to feel. And a still one on a still cloth does not move at all.
TEST(WeaveTracker, FingertipMovingWithTheClothStaysOnItsPoint) {
  WeaveTracker t;
  const Vec3 v(0.03, -0.01, 0.0);
  const Uv first = t.track(flat_anchor(0.01, 0.02, 1.0, v, 0.0), v, 0.0, kDt);
  Uv uv = first;
  for (int k = 1; k <= 300; ++k) uv = t.track(flat_anchor(0.01, 0.02, 1.0, v, k * kDt), v, k * kDt, kDt);
  EXPECT_EQ(uv, first);
  for (int k = 301; k <= 400; ++k)
    uv = t.track(flat_anchor(0.01 + 1e-4, 0.02, 1.0, Vec3::Zero(), k * kDt), Vec3::Zero(), k * kDt, kDt);
  EXPECT_EQ(uv, first);  // not slipping: no pull towards a moved anchor either
}

// Contact lost, the tracker starts again at the next anchor; an invalid anchor stops it.
TEST(WeaveTracker, StartsAgainAtTheAnchorAfterAReset) {
  WeaveTracker t;
  t.track(flat_anchor(0.01, 0.0, 1.0, Vec3::Zero(), 0.0), Vec3(0.02, 0, 0), 0.0, kDt);
  EXPECT_TRUE(t.tracking());
  t.reset();
  EXPECT_FALSE(t.tracking());
  EXPECT_EQ(t.track(flat_anchor(0.07, 0.03, 1.0, Vec3::Zero(), 0.1), Vec3(0.02, 0, 0), 0.1, kDt), Uv(0.07, 0.03));
  t.track(WeaveAnchor{}, Vec3(0.02, 0, 0), 0.2, kDt);
  EXPECT_FALSE(t.tracking());
}
