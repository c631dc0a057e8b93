// The triangle element (eqs. 2-7): exact gradients, Jacobians, invariance, eq. 7 agreement.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <cmath>
#include <random>

#include "cloth/element.hpp"
#include "support/alloc_counter.hpp"
#include "support/fixtures.hpp"

using namespace hapticloth;
using cloth::Mat3;
using cloth::Vec3;

namespace {

using Mat9 = Eigen::Matrix<double, 9, 9>;
using Vec9 = Eigen::Matrix<double, 9, 1>;

cloth::ElementEval eval(const cloth::ElementRest& e, const cloth::Material& m, const Vec3 x[3],
                        const Vec3* v, cloth::JacobianMode mode, bool nonsym = false) {
  const Vec3* xp[3] = {&x[0], &x[1], &x[2]};
  const Vec3* vp[3] = {v ? &v[0] : nullptr, v ? &v[1] : nullptr, v ? &v[2] : nullptr};
  cloth::EvalRequest req;
  req.mode = mode;
  req.viscous_nonsymmetric = nonsym;
  cloth::ElementEval out;
  cloth::evaluate_element(e, m, xp, v ? vp : nullptr, req, out);
  return out;
}

Vec9 forces(const cloth::ElementEval& ev) {
  Vec9 f;
  for (int k = 0; k < 3; ++k) f.segment<3>(3 * k) = ev.f[k];
  return f;
}

Mat9 blocks(const Mat3 (&b)[3][3]) {
  Mat9 M;
  for (int k = 0; k < 3; ++k)
    for (int l = 0; l < 3; ++l) M.block<3, 3>(3 * k, 3 * l) = b[k][l];
  return M;
}

double rel(double err, double ref) { return err / std::max(ref, 1e-300); }

// Central differences of g over the 9 corner coordinates p (positions or velocities): column
// 3k + c is -(g(p + h e) - g(p - h e)) / 2h, e the unit step of corner k along axis c.
template <int Rows, class G>
Eigen::Matrix<double, Rows, 9> minus_central_differences(const Vec3 (&p)[3], G&& g) {
  const double h = 1e-7;
  Eigen::Matrix<double, Rows, 9> d;
  for (int k = 0; k < 3; ++k)
    for (int c = 0; c < 3; ++c) {
      Vec3 pp[3] = {p[0], p[1], p[2]}, pm[3] = {p[0], p[1], p[2]};
      pp[k][c] += h;
      pm[k][c] -= h;
      d.col(3 * k + c) = -(g(pp) - g(pm)) / (2 * h);
    }
  return d;
}

}  // namespace

class ElementFD : public ::testing::TestWithParam<int> {};

// Forces are the exact negative gradient of A * sum Psi(eps).
TEST_P(ElementFD, ForcesAreNegativeEnergyGradient) {
  std::mt19937 rng(1234 + GetParam());
  const auto m = test::denim();
  for (int trial = 0; trial < 20; ++trial) {
    auto t = test::random_triangle(rng, GetParam());
    const Vec9 f = forces(eval(t.rest, m, t.x, nullptr, cloth::JacobianMode::Exact));
    const Vec9 fd = minus_central_differences<1>(t.x, [&](const Vec3 (&x)[3]) {
                      return Eigen::Matrix<double, 1, 1>(cloth::element_energy(t.rest, m, x[0], x[1], x[2]));
                    }).transpose();
    EXPECT_LE(rel((f - fd).norm(), f.norm()), 1e-6) << "trial " << trial;
    // Internal forces sum to zero (translation invariance).
    EXPECT_LE((f.segment<3>(0) + f.segment<3>(3) + f.segment<3>(6)).norm(), 1e-12 * f.norm());
  }
}

// The exact stiffness H = -dF/dP against central differences of the forces.
TEST_P(ElementFD, StiffnessMatchesForceDifferences) {
  std::mt19937 rng(99 + GetParam());
  const auto m = test::denim();
  for (int trial = 0; trial < 20; ++trial) {
    auto t = test::random_triangle(rng, GetParam());
    const Mat9 H = blocks(eval(t.rest, m, t.x, nullptr, cloth::JacobianMode::Exact).H);
    const Mat9 fd = minus_central_differences<9>(
        t.x, [&](const Vec3 (&x)[3]) { return forces(eval(t.rest, m, x, nullptr, cloth::JacobianMode::Exact)); });
    EXPECT_LE(rel((H - fd).norm(), H.norm()), 1e-6) << "trial " << trial;
    EXPECT_LE((H - H.transpose()).norm(), 1e-12 * H.norm()) << "stiffness is not symmetric";
  }
}

// Damping C = -dF/dP' and, with viscosity, the full -dF/dP including its non-symmetric part.
TEST_P(ElementFD, ViscousJacobiansMatchForceDifferences) {
  std::mt19937 rng(7 + GetParam());
  const auto m = test::denim(/*viscosity=*/0.8);
  for (int trial = 0; trial < 20; ++trial) {
    auto t = test::random_triangle(rng, GetParam());
    const auto ev = eval(t.rest, m, t.x, t.v, cloth::JacobianMode::Exact, /*nonsym=*/true);
    const Mat9 C = blocks(ev.C), H = blocks(ev.H);
    const Mat9 fdv = minus_central_differences<9>(
        t.v, [&](const Vec3 (&v)[3]) { return forces(eval(t.rest, m, t.x, v, cloth::JacobianMode::Exact)); });
    const Mat9 fdx = minus_central_differences<9>(
        t.x, [&](const Vec3 (&x)[3]) { return forces(eval(t.rest, m, x, t.v, cloth::JacobianMode::Exact)); });
    EXPECT_LE(rel((C - fdv).norm(), C.norm()), 1e-6) << "trial " << trial;
    EXPECT_LE(rel((H - fdx).norm(), H.norm()), 1e-6) << "trial " << trial;
    EXPECT_LE((C - C.transpose()).norm(), 1e-12 * C.norm());
    // Eq. 6: strain rates are the time derivatives of eq. 4's strains.
    const double dt = 1e-7;
    Vec3 xf[3], xb[3];
    for (int k = 0; k < 3; ++k) {
      xf[k] = t.x[k] + dt * t.v[k];
      xb[k] = t.x[k] - dt * t.v[k];
    }
    const auto sf = cloth::element_strains(t.rest, xf[0], xf[1], xf[2]);
    const auto sb = cloth::element_strains(t.rest, xb[0], xb[1], xb[2]);
    EXPECT_NEAR(ev.eps_rate.uu, (sf.uu - sb.uu) / (2 * dt), 1e-6 * (1 + std::abs(ev.eps_rate.uu)));
    EXPECT_NEAR(ev.eps_rate.vv, (sf.vv - sb.vv) / (2 * dt), 1e-6 * (1 + std::abs(ev.eps_rate.vv)));
    EXPECT_NEAR(ev.eps_rate.uv, (sf.uv - sb.uv) / (2 * dt), 1e-6 * (1 + std::abs(ev.eps_rate.uv)));
  }
}

INSTANTIATE_TEST_SUITE_P(Deformations, ElementFD, ::testing::Values(0, 1, 2),
                         [](const auto& info) {
                           return std::string(info.param == 0   ? "Stretched"
                                              : info.param == 1 ? "Compressed"
                                                                : "StronglySheared");
                         });

// Each element block is positive semi-definite in Spd mode, also compressed and sheared; the
// exact Hessian is not (which is why Spd mode exists).
TEST(Element, SpdModeIsPositiveSemiDefinite) {
  std::mt19937 rng(42);
  const auto m = test::denim(0.5);
  int exact_indefinite = 0;
  for (int kind = 0; kind < 3; ++kind)
    for (int trial = 0; trial < 50; ++trial) {
      auto t = test::random_triangle(rng, kind);
      const Mat9 H = blocks(eval(t.rest, m, t.x, t.v, cloth::JacobianMode::Spd).H);
      const Mat9 C = blocks(eval(t.rest, m, t.x, t.v, cloth::JacobianMode::Spd).C);
      Eigen::SelfAdjointEigenSolver<Mat9> es(H), ec(C);
      EXPECT_GE(es.eigenvalues().minCoeff(), -1e-9 * es.eigenvalues().cwiseAbs().maxCoeff());
      EXPECT_GE(ec.eigenvalues().minCoeff(), -1e-9 * ec.eigenvalues().cwiseAbs().maxCoeff());
      const Mat9 He = blocks(eval(t.rest, m, t.x, nullptr, cloth::JacobianMode::Exact).H);
      Eigen::SelfAdjointEigenSolver<Mat9> ee(He);
      if (ee.eigenvalues().minCoeff() < -1e-6 * ee.eigenvalues().cwiseAbs().maxCoeff())
        ++exact_indefinite;
    }
  EXPECT_GT(exact_indefinite, 20) << "the exact Hessian should be indefinite when compressed or sheared";
}

TEST(Element, InvariantUnderRigidMotion) {
  std::mt19937 rng(5);
  const auto m = test::denim(0.3);
  for (int trial = 0; trial < 20; ++trial) {
    auto t = test::random_triangle(rng, trial % 3);
    const Eigen::Matrix3d R =
        Eigen::AngleAxisd(0.3 + trial, Vec3(1, 2, 3 - trial).normalized()).toRotationMatrix();
    const Vec3 shift(0.7, -2.0, 1.5);
    Vec3 x2[3], v2[3];
    for (int k = 0; k < 3; ++k) {
      x2[k] = R * t.x[k] + shift;
      v2[k] = R * t.v[k];
    }
    const auto a = eval(t.rest, m, t.x, t.v, cloth::JacobianMode::Exact);
    const auto b = eval(t.rest, m, x2, v2, cloth::JacobianMode::Exact);
    EXPECT_NEAR(a.energy, b.energy, 1e-12 * std::abs(a.energy) + 1e-18);
    EXPECT_NEAR(a.eps.uu, b.eps.uu, 1e-12);
    EXPECT_NEAR(a.eps.vv, b.eps.vv, 1e-12);
    EXPECT_NEAR(a.eps.uv, b.eps.uv, 1e-12);
    EXPECT_NEAR(a.eps_rate.uv, b.eps_rate.uv, 1e-10);
    for (int k = 0; k < 3; ++k) {
      EXPECT_LE((R * a.f[k] - b.f[k]).norm(), 1e-10 * (1 + a.f[k].norm()));
      for (int l = 0; l < 3; ++l)
        EXPECT_LE((R * a.H[k][l] * R.transpose() - b.H[k][l]).norm(), 1e-9 * (1 + a.H[k][l].norm()));
    }
  }
}

// Eq. 4: pure shear by an angle gamma gives eps_uv ~ gamma; eq. 2: R coefficients give U = dP/du.
TEST(Element, StrainsOfKnownDeformations) {
  const double uv[3][2] = {{0, 0}, {0.03, 0.0}, {0.01, 0.02}};
  const auto e = cloth::make_element(0, 1, 2, uv);
  EXPECT_NEAR(e.area, 0.5 * 0.03 * 0.02, 1e-15);
  auto place = [&](const Eigen::Matrix<double, 3, 2>& F, Vec3 x[3]) {
    for (int k = 0; k < 3; ++k) x[k] = F * Eigen::Vector2d(uv[k][0], uv[k][1]);
  };
  Vec3 x[3];
  Eigen::Matrix<double, 3, 2> F;
  F << 1.1, 0, 0, 0.95, 0, 0;
  place(F, x);
  auto s = cloth::element_strains(e, x[0], x[1], x[2]);
  EXPECT_NEAR(s.uu, 0.1, 1e-12);
  EXPECT_NEAR(s.vv, -0.05, 1e-12);
  EXPECT_NEAR(s.uv, 0.0, 1e-12);
  const double g = 0.01;  // V tilted towards U by gamma: cos(angle) = sin(gamma)
  F << 1, std::sin(g), 0, std::cos(g), 0, 0;
  place(F, x);
  s = cloth::element_strains(e, x[0], x[1], x[2]);
  EXPECT_NEAR(s.uu, 0.0, 1e-12);
  EXPECT_NEAR(s.vv, 0.0, 1e-12);
  EXPECT_NEAR(s.uv, g, 1e-6);
  const double flat[3][2] = {{0, 0}, {1, 1}, {2, 2}};
  EXPECT_THROW(cloth::make_element(0, 1, 2, flat), std::invalid_argument);
}

// Eq. 7 is the small-shear form of the exact gradient: they agree as shear goes to zero.
TEST(Element, AgreesWithEquation7AsShearVanishes) {
  const double uv[3][2] = {{0, 0}, {0.03, 0.005}, {0.01, 0.02}};
  const auto e = cloth::make_element(0, 1, 2, uv);
  const auto m = test::denim();
  double previous = 1.0;
  for (double g : {1e-1, 1e-2, 1e-3, 1e-4}) {
    Eigen::Matrix<double, 3, 2> F;
    F << 1.05, std::sin(g), 0, std::cos(g) * 1.05, 0, 0;  // stretched 5% along both axes
    // keep |U| = |V| = 1.05 and tilt V by gamma
    F.col(1) = 1.05 * Vec3(std::sin(g), std::cos(g), 0);
    Vec3 x[3];
    for (int k = 0; k < 3; ++k) x[k] = F * Eigen::Vector2d(uv[k][0], uv[k][1]);
    const Vec3* xp[3] = {&x[0], &x[1], &x[2]};
    cloth::ElementEval ev;
    cloth::evaluate_element(e, m, xp, nullptr, cloth::EvalRequest{}, ev);
    Vec3 f7[3];
    cloth::element_forces_eq7(e, m, x[0], x[1], x[2], f7);
    // Compare the shear parts: subtract the (identical) weft/warp parts by using eq. 7 with
    // the full stresses and measuring against the force scale of the shear stress.
    double diff = 0.0, scale = 0.0;
    for (int k = 0; k < 3; ++k) {
      diff = std::max(diff, (ev.f[k] - f7[k]).norm());
      scale = std::max(scale, e.area * std::abs(m.shear.stress(ev.eps.uv)) *
                                  (std::abs(e.ru[k]) + std::abs(e.rv[k])));
    }
    const double r = diff / scale;
    EXPECT_LT(r, 2.0 * g) << "gamma " << g;  // the difference is first order in the shear
    if (g < 1e-1) { EXPECT_LT(r, 0.2 * previous) << "no convergence at gamma " << g; }
    previous = r;
  }
}

// The factored form (P, Q, W) used by the assembly reproduces every block of H and C.
TEST(Element, FactoredJacobiansReproduceBlocks) {
  std::mt19937 rng(17);
  const auto m = test::denim(0.6);
  for (int trial = 0; trial < 30; ++trial) {
    auto t = test::random_triangle(rng, trial % 3);
    const auto ev = eval(t.rest, m, t.x, t.v, cloth::JacobianMode::Spd);
    for (int k = 0; k < 3; ++k)
      for (int l = 0; l < 3; ++l) {
        Mat3 h, c;
        const auto& r = t.rest;
        cloth::combine_blocks(h, r.ru[k] * r.ru[l], ev.P, r.rv[k] * r.rv[l], ev.Q, r.ru[k] * r.rv[l],
                              ev.W, r.rv[k] * r.ru[l]);
        cloth::combine_blocks(c, r.ru[k] * r.ru[l], ev.Pc, r.rv[k] * r.rv[l], ev.Qc,
                              r.ru[k] * r.rv[l], ev.Wc, r.rv[k] * r.ru[l]);
        EXPECT_LE((h - ev.H[k][l]).norm(), 1e-12 * (1 + ev.H[k][l].norm()));
        EXPECT_LE((c - ev.C[k][l]).norm(), 1e-12 * (1 + ev.C[k][l].norm()));
      }
  }
}

TEST(Element, EvaluationAllocatesNothing) {
  std::mt19937 rng(3);
  auto t = test::random_triangle(rng, 2);
  const auto m = test::denim(0.4);
  const Vec3* xp[3] = {&t.x[0], &t.x[1], &t.x[2]};
  const Vec3* vp[3] = {&t.v[0], &t.v[1], &t.v[2]};
  cloth::ElementEval ev;
  cloth::EvalRequest req;
  test::AllocationGuard guard;
  for (int i = 0; i < 100; ++i) cloth::evaluate_element(t.rest, m, xp, vp, req, ev);
  EXPECT_EQ(guard.count(), 0u);
}
