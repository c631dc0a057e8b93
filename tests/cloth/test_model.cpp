// Model set-up (masses, pins, sparsity) and the patch test: uniform strain gives the curve's
// stress exactly, whatever the triangulation and the weave angle.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "cloth/model.hpp"
#include "support/fixtures.hpp"

using namespace hapticloth;
using cloth::Vec3;

TEST(Model, LumpedMassesAndPattern) {
  const cloth::GridSpec g{.width = 0.4, .height = 0.3, .nx = 8, .ny = 6};
  const auto mesh = cloth::make_grid(g);
  const auto pins = cloth::grid_edge(mesh, "top");
  const auto m = cloth::build_model(mesh, test::denim(), pins);
  EXPECT_EQ(m.num_triangles(), 2 * 8 * 6);
  EXPECT_EQ(m.num_vertices(), 9 * 7);
  EXPECT_EQ(m.num_free(), 9 * 6);
  double mass = 0.0;
  for (double x : m.mass) mass += x;
  EXPECT_NEAR(mass, 0.324 * 0.4 * 0.3, 1e-12);
  EXPECT_NEAR(m.total_area, 0.12, 1e-12);
  // The pattern is structurally symmetric, with sorted columns and a diagonal in every row.
  const auto& P = m.pattern;
  for (int r = 0; r < P.n; ++r) {
    EXPECT_GE(P.find(r, r), 0);
    for (int k = P.rowptr[r]; k < P.rowptr[r + 1]; ++k) {
      if (k > P.rowptr[r]) {
        EXPECT_LT(P.col[k - 1], P.col[k]);
      }
      EXPECT_GE(P.find(P.col[k], r), 0);
    }
  }
  EXPECT_THROW(cloth::build_model(mesh, test::denim(), {100000}), std::invalid_argument);
  auto bad = test::denim();
  bad.areal_density = 0.0;
  EXPECT_THROW(cloth::build_model(mesh, bad, pins), std::invalid_argument);
}

class PatchTest : public ::testing::TestWithParam<double> {};

// A sheet of many triangles under a uniform deformation: every element has exactly the imposed
// strains, interior vertices are in equilibrium, and the edge reaction per unit width equals the
// material curve's stress.
TEST_P(PatchTest, UniformStretchGivesCurveStress) {
  const double angle = GetParam();
  cloth::GridSpec g;
  g.width = 0.3;
  g.height = 0.2;
  g.nx = 15;
  g.ny = 10;
  g.weave_angle_deg = angle;
  const auto mesh = cloth::make_grid(g);
  const auto m = cloth::build_model(mesh, test::denim(), {});
  // Stretch eps_u along the weft and eps_v along the warp: x' = Q diag(1+eu, 1+ev) Q^T x.
  const double eu = 0.12, ev = 0.05;
  const double th = angle * M_PI / 180.0;
  const Eigen::Vector3d u(std::cos(th), std::sin(th), 0), v(-std::sin(th), std::cos(th), 0);
  cloth::ClothState s = cloth::rest_state(m);
  for (auto& x : s.x) x = x + eu * x.dot(u) * u + ev * x.dot(v) * v;

  std::vector<Vec3> f(m.num_vertices(), Vec3::Zero());
  cloth::ElementEval out;
  cloth::EvalRequest req;
  req.hessian = false;
  for (const auto& e : m.elements) {
    const Vec3* x[3] = {&s.x[e.v[0]], &s.x[e.v[1]], &s.x[e.v[2]]};
    cloth::evaluate_element(e, m.material, x, nullptr, req, out);
    EXPECT_NEAR(out.eps.uu, eu, 1e-12);
    EXPECT_NEAR(out.eps.vv, ev, 1e-12);
    EXPECT_NEAR(out.eps.uv, 0.0, 1e-12);
    for (int k = 0; k < 3; ++k) f[e.v[k]] += out.f[k];
  }
  const double su = m.material.weft.stress(eu), sv = m.material.warp.stress(ev);
  // Interior vertices: zero net force.
  const int nx = g.nx, ny = g.ny;
  for (int j = 1; j < ny; ++j)
    for (int i = 1; i < nx; ++i)
      EXPECT_LE(f[j * (nx + 1) + i].norm(), 1e-10 * su) << i << "," << j;
  if (angle == 0.0) {
    // Right edge (normal +x = weft): total force = sigma_uu * height; top edge: sigma_vv * width.
    Vec3 right = Vec3::Zero(), top = Vec3::Zero();
    for (int j = 0; j <= ny; ++j) right += f[j * (nx + 1) + nx];
    for (int i = 0; i <= nx; ++i) top += f[ny * (nx + 1) + i];
    // Forces are internal forces on the boundary: they pull inwards with the edge tension.
    EXPECT_NEAR(-right.x() / g.height, su, 1e-10 * su);
    EXPECT_NEAR(-top.y() / g.width, sv, 1e-10 * sv);
    EXPECT_NEAR(right.y(), 0.0, 1e-10 * su);
  }
  // Whatever the angle: the total force on the sheet is zero and the virtual work of the edge
  // forces equals the energy rate: sum f . dx/d(eu) = -A * sigma_uu.
  Vec3 total = Vec3::Zero();
  double work = 0.0;
  for (int i = 0; i < m.num_vertices(); ++i) {
    total += f[i];
    work += f[i].dot(m.rest_positions[i].dot(u) * u);
  }
  EXPECT_LE(total.norm(), 1e-10 * su);
  EXPECT_NEAR(-work, m.total_area * su, 1e-9 * m.total_area * su);
}

INSTANTIATE_TEST_SUITE_P(WeaveAngles, PatchTest, ::testing::Values(0.0, 30.0, 45.0));
