// The refined child mesh (server/haptics/refinement/refined_mesh.hpp): the same continuum as the global
// triangles it refines (areas, masses, weave directions), conforming, graded toward the contact.
#include <gtest/gtest.h>

#include <map>

#include "cloth/mesh.hpp"
#include "cloth/model.hpp"
#include "haptics/refinement/refined_mesh.hpp"
#include "support/fixtures.hpp"

using namespace hapticloth;
using haptics::Vec3;

namespace {
cloth::ClothModel square(int quads, double size, double weave_deg) {
  cloth::GridSpec g;
  g.width = g.height = size;
  g.nx = g.ny = quads;
  g.weave_angle_deg = weave_deg;
  g.origin = {-size / 2, -size / 2, 0.0};
  return cloth::build_model(cloth::make_grid(g), test::denim(), {0});
}
}  // namespace

TEST(RefinedMesh, SameContinuumAsTheTrianglesItRefines) {
  const cloth::ClothModel g = square(9, 0.2, 30.0);  // 22 mm squares, weave at 30 degrees
  haptics::MeshRefiner refiner(g);
  haptics::ClothPoint at;
  at.tri = 80;
  at.b = {0.2, 0.3, 0.5};
  haptics::RefineSpec spec;
  spec.finest = 1e-3;
  spec.reach = 0.035;
  const haptics::RefinedMesh rm = refiner.refine(at, spec);
  const cloth::ClothModel child = cloth::build_model(rm.mesh, g.material, rm.held);
  double area = 0.0;
  for (int t : rm.region) area += g.elements[t].area;
  EXPECT_NEAR(child.total_area, area, 1e-12 * area);
  EXPECT_NEAR(child.total_mass, g.material.areal_density * area, 1e-12);
  EXPECT_LE(rm.finest_edge, spec.finest);
  EXPECT_GT(child.num_triangles(), 100);
  // Weave directions: every child element maps the parent's weave axes the same way, so a
  // uniform stretch of the global cloth gives the same strains in parent and child.
  std::vector<Vec3> gx = g.rest_positions;
  for (auto& x : gx) x = Vec3(1.1 * x.x(), 0.95 * x.y() + 0.02 * x.x(), x.z());
  std::vector<Vec3> cx;
  rm.place(gx, cx);
  for (int t = 0; t < child.num_triangles(); ++t) {
    const auto& e = child.elements[t];
    const cloth::Strains s = cloth::element_strains(e, cx[e.v[0]], cx[e.v[1]], cx[e.v[2]]);
    const auto& ge = g.elements[rm.region[0]];
    const cloth::Strains r = cloth::element_strains(ge, gx[ge.v[0]], gx[ge.v[1]], gx[ge.v[2]]);
    ASSERT_NEAR(s.uu, r.uu, 1e-12);
    ASSERT_NEAR(s.vv, r.vv, 1e-12);
    ASSERT_NEAR(s.uv, r.uv, 1e-12);
  }
  // Conforming: every child edge is used by two child triangles or lies on the region's border.
  std::map<std::pair<int, int>, int> uses;
  for (const auto& t : rm.mesh.triangles)
    for (int k = 0; k < 3; ++k) ++uses[{std::min(t[k], t[(k + 1) % 3]), std::max(t[k], t[(k + 1) % 3])}];
  int border = 0;
  for (const auto& [e, n] : uses) {
    ASSERT_LE(n, 2);
    border += n == 1;
  }
  EXPECT_GT(border, 0);
  for (const auto& [e, n] : uses) {
    if (n != 1) continue;  // a border edge: both ends follow the global cloth
    const bool a = std::find(rm.held.begin(), rm.held.end(), e.first) != rm.held.end();
    const bool b = std::find(rm.held.begin(), rm.held.end(), e.second) != rm.held.end();
    EXPECT_TRUE(a && b) << e.first << " " << e.second;
  }
}
