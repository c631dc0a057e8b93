// The constant part of a cloth simulation (mesh, elements, masses, pins, sparsity pattern) and
// its mutable state. Built once at set-up; stepping never changes a ClothModel.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "cloth/element.hpp"
#include "cloth/mesh.hpp"
#include "cloth/sparse.hpp"

namespace hapticloth::cloth {

struct ClothModel {
  Material material;
  std::vector<ElementRest> elements;
  std::vector<std::array<int, 3>> triangles;  ///< per element, its vertices (the touched surface)
  /// Per element, per corner: its material (weave) coordinates u along the weft, v along the
  /// warp, m (Mesh::weave_uv): where on the fabric's surface a point is (tactile rendering).
  std::vector<std::array<std::array<double, 2>, 3>> weave_uv;
  std::vector<Vec3> rest_positions;
  std::vector<double> mass;         ///< lumped vertex mass, kg (areal density x area / 3)
  std::vector<double> vertex_area;  ///< lumped vertex area, m^2
  std::vector<char> pinned;         ///< 1 if the vertex is kinematic (moves with its velocity)
  std::vector<int> free_index;      ///< vertex -> index among free vertices, or -1 if pinned
  std::vector<int> free_vertices;   ///< free index -> vertex
  double total_mass = 0.0;
  double total_area = 0.0;

  /// System matrix pattern over free vertices (3x3 blocks, both triangles stored).
  SymCsr pattern;
  /// Per element, per (k, l) vertex pair (k * 3 + l): offset in pattern.val of the block's first
  /// row, or -1 if either vertex is pinned. Row a of the block starts at offset + a * row_stride.
  std::vector<std::array<int, 9>> block_offset;
  std::vector<int> row_stride;   ///< per free vertex: scalar entries in each of its three rows
  std::vector<int> diag_offset;  ///< per free vertex: offset of its diagonal block's first row

  int num_vertices() const { return static_cast<int>(rest_positions.size()); }
  int num_free() const { return static_cast<int>(free_vertices.size()); }
  int num_triangles() const { return static_cast<int>(elements.size()); }
  int pins_count() const { return num_vertices() - num_free(); }
};

/// The sparsity pattern of eq. 9 over the free vertices followed by `proxies` massless proxy
/// nodes (fingertips solved with the cloth). A proxy couples to every free vertex, since the
/// cloth it touches changes from step to step; ordered last, its dense rows add no fill-in to a
/// Cholesky factor beyond themselves.
struct SystemPattern {
  SymCsr csr;
  std::vector<std::array<int, 9>> block_offset;  ///< as ClothModel::block_offset
  std::vector<int> row_stride;   ///< per node (free vertices, then proxies)
  std::vector<int> diag_offset;  ///< per node
  int free_nodes = 0, proxies = 0;
  /// Offset of block (node a, node b)'s first row, or -1 outside the pattern. O(log degree).
  int block(int a, int b) const;
};
SystemPattern build_pattern(const ClothModel& model, int proxies);

/// Builds the model: eq. 2 for every triangle, lumped masses, pins and the sparsity pattern.
/// Throws std::invalid_argument for degenerate triangles, bad pin indices or bad density.
ClothModel build_model(const Mesh& mesh, const Material& material, const std::vector<int>& pins);

/// Mutable state: positions (m) and velocities (m/s) of every vertex. Pinned vertices are
/// kinematic: each step moves them with their velocity, which the caller may set.
struct ClothState {
  std::vector<Vec3> x, v;
  double time = 0.0;
};

ClothState rest_state(const ClothModel& model);

/// Mechanical energies of a state (J): kinetic, elastic (sum of A Psi), gravitational.
struct Energies {
  double kinetic = 0, elastic = 0, gravity = 0;
  double total() const { return kinetic + elastic + gravity; }
};
Energies compute_energies(const ClothModel& model, const ClothState& s, const Vec3& gravity);

}  // namespace hapticloth::cloth
