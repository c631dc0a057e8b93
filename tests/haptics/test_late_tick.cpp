// The fingertip a late tick hands the contact (server/haptics/loop/late_tick.hpp).
#include <gtest/gtest.h>

#include "haptics/loop/late_tick.hpp"

using namespace hapticloth;
using haptics::Vec3;

// A tick 20 ms late: the fingertip's jump reaches the contact in 21 equal parts, then the
// fingertip is followed again as measured.
TEST(LateTick, MotionCatchesUpOverTheMissedTicks) {
  haptics::LateTickCatchUp c(1e-3);
  EXPECT_TRUE(c.seen(0, Vec3::Zero(), 0.0).isZero());
  EXPECT_TRUE(c.seen(0, Vec3(0.001, 0, 0), 1e-3).isApprox(Vec3(0.001, 0, 0)));  // on time
  const Vec3 far(0.022, 0, 0);
  Vec3 prev(0.001, 0, 0);
  const Vec3 first = c.seen(0, far, 21e-3);
  EXPECT_NEAR(first.x() - prev.x(), 0.021 / 21, 1e-12);
  prev = first;
  for (int k = 0; k < 20; ++k) {
    const Vec3 s = c.seen(0, far, 1e-3);
    EXPECT_NEAR(s.x() - prev.x(), 0.021 / 21, 1e-12) << k;
    prev = s;
  }
  EXPECT_NEAR(prev.x(), far.x(), 1e-15);
  EXPECT_TRUE(c.seen(0, Vec3(0.023, 0, 0), 1e-3).isApprox(Vec3(0.023, 0, 0)));
  EXPECT_EQ(c.catch_up_ticks(), 21u);
}

// Ticks within half a period of on time are on time; another late tick while catching up
// extends the catch-up; fingers are independent.
TEST(LateTick, JitterIsNotLatenessAndFingersAreIndependent) {
  haptics::LateTickCatchUp c(1e-3);
  EXPECT_FALSE(c.late(1.4e-3));
  EXPECT_TRUE(c.late(1.6e-3));
  c.seen(0, Vec3::Zero(), 0.0);
  c.seen(1, Vec3::Zero(), 0.0);
  EXPECT_TRUE(c.seen(0, Vec3(0.005, 0, 0), 1.4e-3).isApprox(Vec3(0.005, 0, 0)));
  const Vec3 a = c.seen(1, Vec3(0.005, 0, 0), 5e-3);
  EXPECT_NEAR(a.x(), 0.001, 1e-12);
  c.reset(1);
  EXPECT_TRUE(c.seen(1, Vec3(0.007, 0, 0), 1e-3).isApprox(Vec3(0.007, 0, 0)));
}
