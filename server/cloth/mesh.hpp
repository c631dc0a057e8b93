// Triangle mesh with per-corner weave coordinates, and the generated rectangle grid.
#pragma once

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace hapticloth::cloth {

/// A cloth mesh: rest positions (m), triangles, and for each triangle corner its weave
/// coordinates (u along weft, v along warp, in metres of undeformed cloth).
struct Mesh {
  std::vector<Eigen::Vector3d> positions;
  std::vector<std::array<int, 3>> triangles;
  std::vector<std::array<std::array<double, 2>, 3>> weave_uv;  ///< per triangle, per corner
  /// For generated grids: vertex index of grid node (i, j) is j * (nx + 1) + i; 0 otherwise.
  int grid_nx = 0, grid_ny = 0;
};

/// Plane in which a generated grid lies; the grid's first axis maps to the first letter.
enum class GridPlane { XY, XZ, YZ };

struct GridSpec {
  double width = 0.5, height = 0.5;  ///< m, along the grid's first and second axes
  int nx = 22, ny = 22;              ///< quads along each axis (2 triangles per quad)
  double weave_angle_deg = 0.0;      ///< angle of the weft direction from the first axis
  GridPlane plane = GridPlane::XY;
  Eigen::Vector3d origin{0, 0, 0};   ///< position of grid node (0, 0)
  bool alternate_diagonals = true;   ///< alternate the split of neighbouring quads
};

/// Rectangle grid; its rest shape is flat, and the weave axes are rotated by weave_angle_deg.
Mesh make_grid(const GridSpec& spec);

/// Weave coordinates from a flat rest shape: for each triangle, the triangle laid flat in its
/// own plane with the weft axis along `weft_dir3d` projected into that plane.
/// Used when only weave directions (not lengths) are known, e.g. OBJ texture coordinates.
std::array<std::array<double, 2>, 3> flatten_triangle(const Eigen::Vector3d p[3],
                                                      const Eigen::Vector3d& weft_dir3d);

/// Vertices of a generated grid on one named edge: "top" (last row), "bottom", "left", "right".
/// Throws std::invalid_argument for another name or a mesh that is not a grid.
std::vector<int> grid_edge(const Mesh& mesh, const std::string& edge);

}  // namespace hapticloth::cloth
