#include "cloth/mesh.hpp"

#include <cmath>

#include <Eigen/Geometry>
#include <stdexcept>

namespace hapticloth::cloth {

Mesh make_grid(const GridSpec& s) {
  if (s.nx < 1 || s.ny < 1) throw std::invalid_argument("grid resolution must be at least 1 x 1");
  if (!(s.width > 0.0) || !(s.height > 0.0)) throw std::invalid_argument("grid size must be > 0");
  Mesh m;
  m.grid_nx = s.nx;
  m.grid_ny = s.ny;
  Eigen::Vector3d ax(1, 0, 0), ay(0, 1, 0);
  switch (s.plane) {
    case GridPlane::XY: ax = {1, 0, 0}; ay = {0, 1, 0}; break;
    case GridPlane::XZ: ax = {1, 0, 0}; ay = {0, 0, 1}; break;
    case GridPlane::YZ: ax = {0, 1, 0}; ay = {0, 0, 1}; break;
  }
  const double th = s.weave_angle_deg * M_PI / 180.0, c = std::cos(th), sn = std::sin(th);
  std::vector<std::array<double, 2>> uv;
  for (int j = 0; j <= s.ny; ++j) {
    for (int i = 0; i <= s.nx; ++i) {
      const double a = s.width * i / s.nx, b = s.height * j / s.ny;
      m.positions.push_back(s.origin + a * ax + b * ay);
      // weft axis at angle th from the grid's first axis
      uv.push_back({c * a + sn * b, -sn * a + c * b});
    }
  }
  auto id = [&](int i, int j) { return j * (s.nx + 1) + i; };
  auto add = [&](int a, int b, int cc) {
    m.triangles.push_back({a, b, cc});
    m.weave_uv.push_back({uv[a], uv[b], uv[cc]});
  };
  for (int j = 0; j < s.ny; ++j) {
    for (int i = 0; i < s.nx; ++i) {
      const int p00 = id(i, j), p10 = id(i + 1, j), p01 = id(i, j + 1), p11 = id(i + 1, j + 1);
      if (!s.alternate_diagonals || (i + j) % 2 == 0) {
        add(p00, p10, p11);
        add(p00, p11, p01);
      } else {
        add(p00, p10, p01);
        add(p10, p11, p01);
      }
    }
  }
  return m;
}

std::array<std::array<double, 2>, 3> flatten_triangle(const Eigen::Vector3d p[3],
                                                      const Eigen::Vector3d& weft_dir3d) {
  const Eigen::Vector3d e1 = p[1] - p[0], e2 = p[2] - p[0];
  Eigen::Vector3d n = e1.cross(e2);
  const double nn = n.norm();
  if (!(nn > 0.0)) throw std::invalid_argument("degenerate triangle in the rest shape");
  n /= nn;
  Eigen::Vector3d u = weft_dir3d - weft_dir3d.dot(n) * n;  // weft direction in the plane
  if (!(u.norm() > 1e-12)) u = e1;
  u.normalize();
  const Eigen::Vector3d v = n.cross(u);
  std::array<std::array<double, 2>, 3> out;
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d d = p[k] - p[0];
    out[k] = {d.dot(u), d.dot(v)};
  }
  return out;
}

std::vector<int> grid_edge(const Mesh& m, const std::string& edge) {
  if (m.grid_nx <= 0) throw std::invalid_argument("named edges exist only on generated grids");
  std::vector<int> out;
  const int nx = m.grid_nx, ny = m.grid_ny;
  if (edge == "bottom" || edge == "top") {
    const int j = edge == "bottom" ? 0 : ny;
    for (int i = 0; i <= nx; ++i) out.push_back(j * (nx + 1) + i);
  } else if (edge == "left" || edge == "right") {
    const int i = edge == "left" ? 0 : nx;
    for (int j = 0; j <= ny; ++j) out.push_back(j * (nx + 1) + i);
  } else {
    throw std::invalid_argument("unknown edge '" + edge + "' (top, bottom, left, right)");
  }
  return out;
}

}  // namespace hapticloth::cloth
