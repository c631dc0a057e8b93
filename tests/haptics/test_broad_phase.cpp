// BroadPhase (server/haptics/contact/broad_phase.cpp) against brute force: the FCL hierarchy
// must never miss a triangle that a fingertip's sphere reaches, before and after a refit and
// while vertices move within the refit slack (the queries grow by the displacement instead).
#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

#include "cloth/mesh.hpp"
#include "haptics/contact/broad_phase.hpp"
#include "haptics/contact/geometry.hpp"

using namespace hapticloth;
using Eigen::Vector3d;

namespace {

// The triangles within `radius` of `c` (exact closest points), sorted.
std::vector<int> reached(const std::vector<Vector3d>& x, const std::vector<std::array<int, 3>>& tris,
                         const Vector3d& c, double radius) {
  std::vector<int> out;
  for (int t = 0; t < static_cast<int>(tris.size()); ++t) {
    const auto& v = tris[t];
    if (haptics::closest_point_triangle(c, x[v[0]], x[v[1]], x[v[2]]).dist2 <= radius * radius) out.push_back(t);
  }
  return out;
}

std::vector<int> query(haptics::BroadPhase& bp, const Vector3d& c, double radius) {
  std::vector<int> out(4096);
  out.resize(bp.query_sphere(c, radius, out.data(), static_cast<int>(out.size())));
  return out;
}

bool contains_all(const std::vector<int>& found, const std::vector<int>& needed) {
  return std::includes(found.begin(), found.end(), needed.begin(), needed.end());
}

}  // namespace

TEST(BroadPhase, FindsEveryTriangleTheSphereReachesAsTheClothMoves) {
  cloth::GridSpec g{.width = 0.2, .height = 0.2, .nx = 20, .ny = 20};
  const cloth::Mesh mesh = cloth::make_grid(g);
  std::vector<Vector3d> x = mesh.positions;
  haptics::BroadPhase bp(x, mesh.triangles, 0.005);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> at(0.0, 0.2), bump(-1.0, 1.0);
  int nonempty = 0;
  for (int round = 0; round < 40; ++round) {
    // Every vertex moves by up to 3 mm a round: some rounds stay within the 5 mm slack since the
    // last refit (the query grows), others pass it (update refits).
    for (auto& p : x) p += 0.0017 * Vector3d(bump(rng), bump(rng), bump(rng));
    bp.update(x);
    EXPECT_LE(bp.displacement(), 0.005 + 1e-12);
    for (int q = 0; q < 10; ++q) {
      const Vector3d c(at(rng), at(rng), 0.006 * bump(rng));
      const std::vector<int> need = reached(x, mesh.triangles, c, 0.008);
      const std::vector<int> found = query(bp, c, 0.008);
      ASSERT_TRUE(std::is_sorted(found.begin(), found.end()));
      ASSERT_TRUE(std::adjacent_find(found.begin(), found.end()) == found.end()) << "unique";
      EXPECT_TRUE(contains_all(found, need)) << "round " << round << ": a reached triangle was missed";
      nonempty += !need.empty();
    }
  }
  EXPECT_GT(nonempty, 200);    // the spheres did touch the cloth
  EXPECT_GT(bp.refits(), 3u);  // and the slack was passed, so refits were exercised
}

TEST(BroadPhase, AFarSphereFindsNothingAndTheOutputIsBounded) {
  const cloth::Mesh mesh = cloth::make_grid(cloth::GridSpec{.width = 0.1, .height = 0.1, .nx = 10, .ny = 10});
  haptics::BroadPhase bp(mesh.positions, mesh.triangles);
  EXPECT_TRUE(query(bp, Vector3d(1.0, 1.0, 1.0), 0.01).empty());
  // A sphere over the whole cloth reaches all 200 triangles; at most max_out are written.
  std::vector<int> out(16);
  EXPECT_EQ(bp.query_sphere(Vector3d(0.05, 0.05, 0.0), 0.2, out.data(), 16), 16);
  EXPECT_EQ(query(bp, Vector3d(0.05, 0.05, 0.0), 0.2).size(), 200u);
}
