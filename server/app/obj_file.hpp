// Wavefront OBJ meshes with texture coordinates.
#pragma once

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace hapticloth::app {

struct ObjMesh {
  std::vector<Eigen::Vector3d> positions;
  std::vector<Eigen::Vector2d> texcoords;
  std::vector<std::array<int, 3>> triangles;           ///< position indices (0-based)
  std::vector<std::array<int, 3>> triangle_texcoords;  ///< texcoord indices, -1 if absent
  std::vector<int> triangle_lines;                     ///< line of the face record in the file
};

/// Reads v, vt and f records (polygons are fan-triangulated; other records are ignored).
/// Throws ConfigError with file and line for malformed records and out-of-range indices.
ObjMesh load_obj(const std::string& path);

}  // namespace hapticloth::app
