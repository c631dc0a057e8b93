// The elements split for two-thread assembly (server/cloth/element_partition): parts that share
// no vertex, every element once, in its order.
#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <random>
#include <set>

#include "cloth/element_partition.hpp"
#include "support/fixtures.hpp"

using namespace hapticloth;

TEST(ElementPartition, PartsShareNoVertexAndCoverEveryElementOnce) {
  cloth::GridSpec g;
  g.nx = g.ny = 40;
  const cloth::ClothModel m = cloth::build_model(cloth::make_grid(g), test::denim(0.0), {});
  for (int parts : {1, 2, 4, 8}) {
    const cloth::ElementPartition p = cloth::partition_elements(m.elements, m.rest_positions, parts);
    ASSERT_EQ(static_cast<int>(p.parts.size()), parts);
    std::vector<int> owner(m.num_vertices(), -1), seen(m.num_triangles(), 0);
    for (int k = 0; k < parts; ++k) {
      EXPECT_TRUE(std::is_sorted(p.parts[k].begin(), p.parts[k].end()));
      // balanced: each part holds close to its share of the 3200 elements
      EXPECT_GT(static_cast<int>(p.parts[k].size()), 0.8 * m.num_triangles() / parts - 100);
      for (int t : p.parts[k]) {
        ++seen[t];
        for (int v : m.elements[t].v) {
          EXPECT_TRUE(owner[v] < 0 || owner[v] == k) << "vertex " << v << " in parts " << owner[v] << " and " << k;
          owner[v] = k;
        }
      }
    }
    EXPECT_TRUE(std::is_sorted(p.separators.begin(), p.separators.end()));
    for (int t : p.separators) ++seen[t];
    for (int t = 0; t < m.num_triangles(); ++t) EXPECT_EQ(seen[t], 1) << "element " << t;
    // the separators are the cuts' rows of elements: 40 quads wide, a few hundred at most
    EXPECT_LE(static_cast<int>(p.separators.size()), parts == 1 ? 0 : 2 * 80 * (parts - 1));
  }
  EXPECT_THROW(cloth::partition_elements(m.elements, m.rest_positions, 3), std::invalid_argument);
}

// The first cut is by vertex number when that crosses few elements (a grid numbered row by
// row: the caller's parts 0 and 1 are the mesh's first half, which the PCG's caller sweeps),
// and by position when the numbering is scattered (the same grid renumbered at random: a cut by
// number would cross nearly every element).
TEST(ElementPartition, TheFirstCutFollowsTheNumberingWhenItIsLocal) {
  cloth::GridSpec g;
  g.nx = g.ny = 40;
  const cloth::ClothModel m = cloth::build_model(cloth::make_grid(g), test::denim(0.0), {});
  const int nv = m.num_vertices();
  const cloth::ElementPartition p = cloth::partition_elements(m.elements, m.rest_positions, 4);
  for (int k = 0; k < 4; ++k)
    for (int t : p.parts[k])
      for (int v : m.elements[t].v) EXPECT_EQ(v >= nv / 2, k >= 2) << "part " << k << ", vertex " << v;
  std::vector<int> to(nv);
  std::iota(to.begin(), to.end(), 0);
  std::mt19937 rng(5);
  std::shuffle(to.begin(), to.end(), rng);
  std::vector<cloth::Vec3> x(nv);
  std::vector<cloth::ElementRest> elements = m.elements;
  for (int i = 0; i < nv; ++i) x[to[i]] = m.rest_positions[i];
  for (auto& e : elements)
    for (int& v : e.v) v = to[v];
  const cloth::ElementPartition q = cloth::partition_elements(elements, x, 4);
  // By number, most of the 3200 elements would be separators; by position, the cuts' rows.
  EXPECT_LE(static_cast<int>(q.separators.size()), 2 * 80 * 3);
}
