// The refined children under the fingertips as a viewer draws them (cloth_state_t's refined
// fields): every child's vertices, triangles and weave coordinates one after another, and the
// global triangles the children stand in for. Gathered by the refinement schedule after each
// update, on the thread that ran it; published at the cloth rate with the global positions.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

namespace hapticloth::haptics {

class LocalRefinement;

struct RefinedRegions {
  using Vec3 = Eigen::Vector3d;
  std::uint64_t version = 0;  ///< the refinement update gathered (0: none yet)
  std::vector<Vec3> x;        ///< m, the children's vertices
  std::vector<std::array<int, 3>> triangles;                  ///< into x
  std::vector<std::array<std::array<double, 2>, 3>> weave_uv;  ///< m, per triangle and corner
  std::vector<int> region;    ///< global triangles the children stand in for

  /// The children `r` has after its update number `update`, for its first `fingers` fingers
  /// (none where a finger has no child). Keeps this object's storage: allocates only when the
  /// children grow.
  void gather(const LocalRefinement& r, int fingers, std::uint64_t update);
  bool empty() const { return triangles.empty(); }
};

}  // namespace hapticloth::haptics
