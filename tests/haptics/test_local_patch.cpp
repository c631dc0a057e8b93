// The paper's local refinement (server/haptics/local_patch, section 4.2): a patch is built
// from the triangles the simulation thread listed for the finger, so its cost on the haptic
// thread follows the patch, not the mesh; its border is the boundary of the selected triangles.
#include <gtest/gtest.h>

#include <map>
#include <set>
#include <utility>

#include "cloth/mesh.hpp"
#include "haptics/modes/local_patch.hpp"

using namespace hapticloth;
using haptics::Vec3;

namespace {

struct Flat {
  cloth::Mesh mesh;
  std::vector<char> pinned;
  haptics::ClothSnapshot snap;
};

// A flat 0.2 m square of 40 x 40 quads (3200 triangles) at rest, the snapshot listing for
// finger 0 the triangles whose index passes `listed`.
template <class Listed>
Flat flat(Listed listed) {
  cloth::GridSpec g;
  g.width = g.height = 0.2;
  g.nx = g.ny = 40;
  Flat f{cloth::make_grid(g), {}, {}};
  const int nv = static_cast<int>(f.mesh.positions.size()), nt = static_cast<int>(f.mesh.triangles.size());
  f.pinned.assign(nv, 0);
  f.snap.resize(nv, nt);
  f.snap.time = 0.0;
  std::copy(f.mesh.positions.begin(), f.mesh.positions.end(), f.snap.x.begin());
  int n = 0;
  for (int t = 0; t < nt; ++t)
    if (listed(t)) f.snap.near_triangles[0][n++] = t;
  f.snap.near_count[0] = n;
  return f;
}

haptics::PatchParams params() {
  haptics::PatchParams p;
  p.radius = 0.012;
  p.max_triangles = 192;
  return p;
}

}  // namespace

// Listing every triangle or only those near the finger gives the same patch: the selection
// is by distance among what is listed.
TEST(LocalPatch, BuildsTheSamePatchFromTheNearTrianglesAsFromAll) {
  const Vec3 c(0.1, 0.1, 0.004);
  Flat all = flat([](int) { return true; });
  Flat near = flat([](int) { return false; });
  int n = 0;
  for (int t = 0; t < static_cast<int>(all.mesh.triangles.size()); ++t) {
    bool in = false;
    for (int k = 0; k < 3; ++k) in = in || (all.mesh.positions[all.mesh.triangles[t][k]] - c).norm() < 0.02;
    if (in) near.snap.near_triangles[0][n++] = t;
  }
  near.snap.near_count[0] = n;
  ASSERT_LT(n, 400);  // a few hundred of the 3200
  haptics::LocalPatch a(all.mesh.triangles, all.mesh.positions, all.pinned, params());
  haptics::LocalPatch b(near.mesh.triangles, near.mesh.positions, near.pinned, params());
  a.rebuild(all.snap, 0, c);
  b.rebuild(near.snap, 0, c);
  ASSERT_TRUE(a.active());
  EXPECT_EQ(a.triangles(), b.triangles());
  EXPECT_EQ(a.vertices(), b.vertices());
  for (int t = 0; t < a.triangles(); t += 4) EXPECT_EQ(a.global_triangle(t), b.global_triangle(t));
}

// The build reads only the listed triangles: with none listed there is no patch, although the
// mesh is right under the finger.
TEST(LocalPatch, TakesOnlyTheTrianglesTheSnapshotLists) {
  Flat none = flat([](int) { return false; });
  haptics::LocalPatch p(none.mesh.triangles, none.mesh.positions, none.pinned, params());
  p.rebuild(none.snap, 0, Vec3(0.1, 0.1, 0.004));
  EXPECT_FALSE(p.active());
  // Finger 1's list is its own: finger 0's triangles do not build finger 1's patch.
  Flat all = flat([](int) { return true; });
  p.rebuild(all.snap, 1, Vec3(0.1, 0.1, 0.004));
  EXPECT_FALSE(p.active());
}

// The border is the boundary of the selected triangles: a global edge used by one of them. The
// reference counts the uses of every edge among the selected triangles.
TEST(LocalPatch, BorderIsTheBoundaryOfTheSelectedTriangles) {
  Flat all = flat([](int) { return true; });
  haptics::LocalPatch p(all.mesh.triangles, all.mesh.positions, all.pinned, params());
  p.rebuild(all.snap, 0, Vec3(0.1, 0.1, 0.004));
  ASSERT_TRUE(p.active());
  std::map<std::pair<int, int>, int> uses;
  std::set<int> selected;
  for (int t = 0; t < p.triangles(); t += 4) selected.insert(p.global_triangle(t));
  for (int t : selected)
    for (int k = 0; k < 3; ++k) {
      int a = all.mesh.triangles[t][k], b = all.mesh.triangles[t][(k + 1) % 3];
      if (a > b) std::swap(a, b);
      ++uses[{a, b}];
    }
  std::set<int> boundary_vertices;  // global vertices on a boundary edge
  int boundary_edges = 0;
  for (const auto& [e, n] : uses)
    if (n == 1) {
      boundary_vertices.insert(e.first);
      boundary_vertices.insert(e.second);
      ++boundary_edges;
    }
  int border = 0;
  for (int v = 0; v < p.vertices(); ++v) border += p.border(v);
  // Border patch vertices: the global vertices on the boundary and the boundary edges' midpoints.
  EXPECT_GE(boundary_edges, 12);
  EXPECT_EQ(border, static_cast<int>(boundary_vertices.size()) + boundary_edges);
}
