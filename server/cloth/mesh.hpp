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

/// Graded disc (flat, plane z = centre.z): rings of vertices whose radial spacing grows
/// geometrically from `centre_edge` by `growth` per ring until it reaches `rim_edge`, after
/// which it is kept; the last ring lies exactly at `radius`.
struct DiscSpec {
  double radius = 0.1;         ///< m, rest radius of the disc
  double centre_edge = 0.001;  ///< m, target edge length at the centre
  double rim_edge = 0.005;     ///< m, largest edge length (reached by geometric growth, then kept)
  double growth = 1.12;        ///< edge-length ratio between neighbouring rings (>= 1)
  Eigen::Vector3d centre{0, 0, 0};
};

/// Graded disc mesh: a centre vertex with a hexagonal fan, then rings k = 1..K at radii r_k
/// holding about 2 pi r_k / h_k vertices (h_k the local radial spacing), consecutive rings
/// joined by advancing along both rings and taking the shorter diagonal. Triangles are
/// counter-clockwise seen from +z. weave_uv per corner = rest (x - centre.x, y - centre.y)
/// (weft along x); grid_nx = grid_ny = 0. Throws std::invalid_argument naming the bad field
/// (every length positive and finite, centre_edge <= rim_edge < radius, growth >= 1).
Mesh make_disc(const DiscSpec& spec);

/// Vertices of the outer boundary loop of a mesh (for make_disc: the rim ring), in
/// counter-clockwise order. Found from the edges used by a single triangle; when there are
/// several boundary loops the longest is returned. Throws std::invalid_argument if the mesh
/// has no boundary.
std::vector<int> disc_rim(const Mesh& mesh);

}  // namespace hapticloth::cloth
