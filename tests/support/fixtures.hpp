// Shared test fixtures: materials built inline, random deformed triangles.
#pragma once

#include <initializer_list>
#include <random>
#include <vector>

#include <Eigen/Geometry>

#include "cloth/element.hpp"
#include "cloth/material.hpp"
#include "cloth/mesh.hpp"
#include "cloth/model.hpp"

namespace hapticloth::test {

/// Denim-like material (the hand-made spline of tools/materials/denim-handmade.toml), with
/// optional viscosity on all three curves and a stiffness scale.
inline cloth::Material denim(double viscosity = 0.0, double scale = 1.0) {
  cloth::Material m;
  m.name = "denim-test";
  m.areal_density = 0.324;
  m.weft.segments = 2;
  m.weft.knots = {0.0, 0.17, 0.0};
  m.weft.B[0] = {0.0, 399.4 * scale, 1208.0 * scale, -659.2 * scale};
  m.weft.B[1] = {0.0, 0.0, -585.9 * scale, 3378.8 * scale};
  m.warp.B[0] = {0.0, 2003.9 * scale, 3892.9 * scale, 271.2 * scale};
  m.shear.B[0] = {0.0, 53.4 * scale, 90.8 * scale, 7.8 * scale};
  m.shear.odd = true;
  m.weft.viscosity = viscosity;
  m.warp.viscosity = 2.0 * viscosity;
  m.shear.viscosity = 0.5 * viscosity;
  return m;
}

/// A horizontal square of cloth (z = 0, centred on the origin), n x n quads, pinned on the named
/// grid edges ("top", "bottom", "left", "right").
inline cloth::ClothModel square_cloth(const cloth::Material& m,
                                      std::initializer_list<const char*> pinned_edges, int n = 20,
                                      double size = 0.3) {
  cloth::GridSpec g;
  g.width = g.height = size;
  g.nx = g.ny = n;
  g.origin = {-size / 2, -size / 2, 0.0};
  const auto mesh = cloth::make_grid(g);
  std::vector<int> pins;
  for (const char* e : pinned_edges)
    for (int v : cloth::grid_edge(mesh, e)) pins.push_back(v);
  return cloth::build_model(mesh, m, pins);
}

/// A horizontal square of denim (z = 0, centred on the origin) pinned on its four edges, n x n
/// quads: the drum of the haptics tests.
inline cloth::ClothModel denim_drum(int n = 20, double size = 0.3) {
  return square_cloth(denim(), {"top", "bottom", "left", "right"}, n, size);
}

/// A triangle in weave space and a random deformation of it: `kind` 0 = mild stretch,
/// 1 = compressed, 2 = strongly sheared.
struct RandomTriangle {
  cloth::ElementRest rest;
  cloth::Vec3 x[3];
  cloth::Vec3 v[3];
};

inline RandomTriangle random_triangle(std::mt19937& rng, int kind) {
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  RandomTriangle t;
  double uv[3][2];
  for (;;) {
    for (auto& c : uv) {
      c[0] = 0.02 * U(rng);
      c[1] = 0.02 * U(rng);
    }
    const double d = uv[0][0] * (uv[1][1] - uv[2][1]) + uv[1][0] * (uv[2][1] - uv[0][1]) +
                     uv[2][0] * (uv[0][1] - uv[1][1]);
    if (std::abs(d) > 1e-4) break;  // not too thin
  }
  t.rest = cloth::make_element(0, 1, 2, uv);
  // Deformation gradient from weave plane to 3D, then a random rotation and small noise.
  Eigen::Matrix<double, 3, 2> F;
  double su = 1.0 + 0.1 * U(rng), sv = 1.0 + 0.1 * U(rng), sh = 0.1 * U(rng);
  if (kind == 1) {
    su = 0.8 + 0.1 * U(rng);
    sv = 0.85 + 0.1 * U(rng);
  } else if (kind == 2) {
    sh = 0.6 + 0.3 * U(rng);  // ~30-50 degrees of shear
    if (U(rng) < 0) sh = -sh;
  }
  F << su, sh, 0.0, sv, 0.05 * U(rng), 0.05 * U(rng);
  const Eigen::Quaterniond q = Eigen::Quaterniond(U(rng), U(rng), U(rng), U(rng)).normalized();
  const cloth::Vec3 shift(U(rng), U(rng), U(rng));
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector2d p(uv[k][0], uv[k][1]);
    t.x[k] = q * (F * p) + shift + cloth::Vec3(U(rng), U(rng), U(rng)) * 1e-3;
    t.v[k] = cloth::Vec3(U(rng), U(rng), U(rng));
  }
  return t;
}

}  // namespace hapticloth::test
