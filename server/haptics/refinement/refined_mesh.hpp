// The refined child mesh under a fingertip (paper 4.2.2, local refinement): the global triangles
// near the contact, bisected toward the contact point until the contact patch is resolved.
//
// The refinement is geometric subdivision in the material: every child triangle lies inside one
// global triangle, its weave coordinates are that triangle's interpolated (so eq. 2 gives the
// same weave directions and the same laws, eqs. 3-7, apply), and its area is a part of that
// triangle's, so the lumped masses (density x area / 3) redistribute the region's mass exactly.
// Bisection is Rivara's longest-edge bisection: a triangle is split at the midpoint of its
// longest edge and a neighbour holding that midpoint on one of its own edges is split in turn,
// so the child mesh is conforming and its angles stay bounded away from zero.
//
// Where the region meets the rest of the cloth its border follows the global cloth (those child
// vertices lie on global edges, and are placed by linear interpolation, as the global elements
// place them). Border edges that are the cloth's own free boundary stay free.
#pragma once

#include <array>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include "cloth/mesh.hpp"
#include "cloth/model.hpp"

namespace hapticloth::haptics {

using Vec3 = Eigen::Vector3d;

struct RefineSpec {
  double finest = 1e-3;  ///< m: edge length at the contact point
  /// Edge length grows as grading x distance from the contact point (a graded mesh: the
  /// membrane's dimple w ~ ln r changes on the scale of r).
  double grading = 0.5;
  double reach = 0.03;  ///< m: global triangles with a corner within it (rest) are refined
};

/// A point of the global cloth: triangle and barycentric weights.
struct ClothPoint {
  int tri = -1;
  std::array<double, 3> b{0.0, 0.0, 0.0};
};

struct RefinedMesh {
  cloth::Mesh mesh;           ///< rest positions, child triangles and their weave coordinates
  std::vector<int> held;      ///< child vertices that follow the global cloth (border, pins)
  std::vector<ClothPoint> at;  ///< per child vertex: where it lies in the global cloth
  std::vector<std::array<int, 3>> tri_vertices;  ///< per child vertex: its global triangle's corners
  std::vector<int> region;    ///< the global triangles it refines
  double finest_edge = 0.0;   ///< m, shortest edge made
  /// Child positions from the global cloth's (linear interpolation in the global triangles).
  void place(const std::vector<Vec3>& global_x, std::vector<Vec3>& x) const;
};

class MeshRefiner {
 public:
  /// `global` must outlive the refiner (its rest positions, triangles, elements and pins).
  explicit MeshRefiner(const cloth::ClothModel& global);

  /// The child mesh around the global point `contact` (rest coordinates).
  RefinedMesh refine(const ClothPoint& contact, const RefineSpec& spec) const;

  /// Longest rest edge of global triangle `t`, m.
  double longest_edge(int t) const;
  /// Rest position of a global point.
  Vec3 rest_point(const ClothPoint& p) const;

 private:
  std::vector<int> region_around(const ClothPoint& contact, double reach) const;
  std::vector<int> held_children(const RefinedMesh& out) const;

  const cloth::ClothModel& g_;
  std::unordered_map<std::uint64_t, int> edge_uses_;  // global edge -> triangles using it
  std::vector<std::vector<int>> vertex_tris_;          // global vertex -> its triangles
};

}  // namespace hapticloth::haptics
