// The geometry of the narrow phase (server/haptics/geometry): closest points on a triangle.
#include <gtest/gtest.h>

#include <random>

#include "haptics/contact/geometry.hpp"
#include "support/fixtures.hpp"

using namespace hapticloth;
using haptics::Vec3;

TEST(Geometry, ClosestPointOnTriangleRegions) {
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  auto cp = haptics::closest_point_triangle(Vec3(0.2, 0.2, 0.5), a, b, c);  // face
  EXPECT_TRUE(cp.point.isApprox(Vec3(0.2, 0.2, 0), 1e-12));
  EXPECT_NEAR(cp.dist2, 0.25, 1e-12);
  EXPECT_NEAR(cp.b[0] + cp.b[1] + cp.b[2], 1.0, 1e-12);
  cp = haptics::closest_point_triangle(Vec3(-1, -1, 0), a, b, c);  // vertex a
  EXPECT_EQ(cp.point, a);
  cp = haptics::closest_point_triangle(Vec3(1, 1, 0), a, b, c);  // edge bc
  EXPECT_TRUE(cp.point.isApprox(Vec3(0.5, 0.5, 0), 1e-12));
  cp = haptics::closest_point_triangle(Vec3(0.5, -2, 1), a, b, c);  // edge ab
  EXPECT_TRUE(cp.point.isApprox(Vec3(0.5, 0, 0), 1e-12));
}
