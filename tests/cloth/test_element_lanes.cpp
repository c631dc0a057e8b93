// The element pass on lanes (cloth/element_lanes): the material laws on lanes against the scalar
// law on every branch, the grouping of elements, a group's terms against evaluate_element, and
// their blocks moved into rows for the scatter.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "cloth/curve.hpp"
#include "cloth/element_lanes.hpp"
#include "support/fixtures.hpp"

using namespace hapticloth;
using cloth::kLanes;
using cloth::Lanes;
using cloth::Mat3;
using cloth::Vec3;

namespace {

// Three segments, compression at half the initial slope, validated to 12% strain: strains
// from -0.3 to 0.3 cross every branch (compression, each segment, the linear continuation).
cloth::StrainStressCurve tensile_law() {
  cloth::StrainStressCurve c;
  c.segments = 3;
  c.knots = {0.0, 0.03, 0.08};
  c.B[0] = {1.5, 300.0, 500.0, 100.0};
  c.B[1] = {0.0, 0.0, 2000.0, -1000.0};
  c.B[2] = {0.0, 0.0, 8000.0, 20000.0};
  c.compression_scale = 0.5;
  c.max_strain = 0.12;
  return c;
}

cloth::StrainStressCurve shear_law() {
  cloth::StrainStressCurve c;
  c.segments = 2;
  c.knots = {0.0, 0.05, 0.0};
  c.B[0] = {0.0, 53.4, 90.8, 7.8};
  c.B[1] = {0.0, 0.0, 400.0, 100.0};
  c.odd = true;
  c.max_strain = 0.1;
  return c;
}

}  // namespace

TEST(ElementLanes, LawOnLanesEqualsTheScalarLawOnEveryBranch) {
  for (const cloth::StrainStressCurve& c : {tensile_law(), shear_law()}) {
    int checked = 0;
    for (int base = 0; base < 75; base += kLanes) {
      Lanes eps;
      for (int l = 0; l < kLanes; ++l) eps[l] = -0.3 + 0.6 * (base + l) / 74.0;
      Lanes psi, s, ds;
      cloth::evaluate_lanes(c, eps, psi, s, ds);
      for (int l = 0; l < kLanes; ++l) {
        double psi_ref, s_ref, ds_ref;
        c.evaluate_all(eps[l], psi_ref, s_ref, ds_ref);
        const double tol = 1e-13 * (1.0 + std::abs(s_ref) + std::abs(ds_ref));
        EXPECT_NEAR(psi[l], psi_ref, tol) << "eps " << eps[l];
        EXPECT_NEAR(s[l], s_ref, tol) << "eps " << eps[l];
        EXPECT_NEAR(ds[l], ds_ref, tol) << "eps " << eps[l];
        ++checked;
      }
    }
    EXPECT_GE(checked, 75);
  }
}

// 11 elements make a full group and one of 3 real lanes, whose other lanes repeat its last
// element (so that they compute something finite) and are not counted.
TEST(ElementLanes, GroupsKeepTheOrderAndPadTheLastGroup) {
  std::mt19937 rng(5);
  std::vector<cloth::ElementRest> elements;
  for (int i = 0; i < 20; ++i) elements.push_back(test::random_triangle(rng, 0).rest);
  const std::vector<int> order = {19, 3, 4, 0, 7, 8, 12, 11, 2, 5, 17};
  const auto groups = cloth::group_elements(elements, order);
  ASSERT_EQ(groups.size(), 2u);
  EXPECT_EQ(groups[0].count, kLanes);
  EXPECT_EQ(groups[1].count, 3);
  for (int i = 0; i < 11; ++i) {
    const auto& g = groups[i / kLanes];
    const int l = i % kLanes;
    const auto& e = elements[order[i]];
    EXPECT_EQ(g.t[l], order[i]);
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(g.v[k][l], e.v[k]);
      EXPECT_EQ(g.ru[k][l], e.ru[k]);
      EXPECT_EQ(g.rv[k][l], e.rv[k]);
    }
    EXPECT_EQ(g.area[l], e.area);
  }
  for (int l = 3; l < kLanes; ++l) EXPECT_EQ(groups[1].t[l], 17);
  EXPECT_TRUE(cloth::group_elements(elements, {}).empty());
}

// Each lane's terms against evaluate_element of its element: right-hand side
// h (f_k - alpha h sum_l H_kl v_l) and blocks alpha^2 h^2 H_kl + alpha h C_kl, with viscosity,
// in both Jacobian modes, on stretched, compressed and sheared triangles.
TEST(ElementLanes, TermsEqualTheElementEvaluation) {
  const double h = 0.004, alpha = 0.8;
  for (const double viscosity : {0.0, 0.05})
    for (const auto mode : {cloth::JacobianMode::Spd, cloth::JacobianMode::Exact}) {
      const cloth::Material mat = test::denim(viscosity);
      std::mt19937 rng(11);
      std::vector<cloth::ElementRest> elements;
      std::vector<Vec3> x, v;
      for (int i = 0; i < kLanes; ++i) {
        const auto t = test::random_triangle(rng, i % 3);
        cloth::ElementRest e = t.rest;
        for (int k = 0; k < 3; ++k) {
          e.v[k] = static_cast<int>(x.size());
          x.push_back(t.x[k]);
          v.push_back(t.v[k]);
        }
        elements.push_back(e);
      }
      std::vector<int> order(kLanes);
      for (int i = 0; i < kLanes; ++i) order[i] = i;
      const cloth::ElementGroup g = cloth::group_elements(elements, order)[0];
      cloth::ElementTerms terms;
      const cloth::StepFactors f{h, alpha};
      if (viscosity > 0.0)
        mode == cloth::JacobianMode::Spd ? cloth::element_terms<true, true>(g, mat, x.data(), v.data(), f, terms)
                                         : cloth::element_terms<true, false>(g, mat, x.data(), v.data(), f, terms);
      else
        mode == cloth::JacobianMode::Spd ? cloth::element_terms<false, true>(g, mat, x.data(), v.data(), f, terms)
                                         : cloth::element_terms<false, false>(g, mat, x.data(), v.data(), f, terms);
      cloth::system_blocks(g, terms.factor, terms.block);
      for (int l = 0; l < kLanes; ++l) {
        const auto& e = elements[l];
        const Vec3* xp[3] = {&x[e.v[0]], &x[e.v[1]], &x[e.v[2]]};
        const Vec3* vp[3] = {&v[e.v[0]], &v[e.v[1]], &v[e.v[2]]};
        cloth::EvalRequest req;
        req.mode = mode;
        cloth::ElementEval ev;
        cloth::evaluate_element(e, mat, xp, vp, req, ev);
        EXPECT_NEAR(terms.energy[l], ev.energy, 1e-12 * std::abs(ev.energy) + 1e-18);
        for (int k = 0; k < 3; ++k) {
          Vec3 Hv = Vec3::Zero();
          for (int m = 0; m < 3; ++m) Hv += ev.H[k][m] * *vp[m];
          const Vec3 rhs = h * (ev.f[k] - alpha * h * Hv);
          for (int r = 0; r < 3; ++r)
            EXPECT_NEAR(terms.rhs[k][r][l], rhs[r], 1e-12 * (1.0 + rhs.norm())) << "lane " << l;
          for (int m = k; m < 3; ++m) {
            const Mat3 ref = alpha * alpha * h * h * ev.H[k][m] + alpha * h * ev.C[k][m];
            const Lanes* blk = terms.block[cloth::kPair[k][m]];
            for (int c = 0; c < 3; ++c)
              for (int r = 0; r < 3; ++r)
                EXPECT_NEAR(blk[3 * c + r][l], ref(r, c), 1e-12 * (1e-9 + ref.norm()))
                    << "lane " << l << " block " << k << m;
          }
        }
      }
    }
}

// lane_blocks moves each lane's blocks into rows (an 8x8 transpose in registers with AVX-512):
// every entry lands where the scatter reads it, row-major, and the transposes of the blocks
// (k, l), k < l, row-major too. Each entry of the terms is distinct.
TEST(ElementLanes, LaneBlocksHoldEachLanesBlocksRowByRow) {
  cloth::ElementTerms terms;
  for (int p = 0; p < 6; ++p)
    for (int j = 0; j < 9; ++j)
      for (int l = 0; l < cloth::kLanes; ++l) terms.block[p][j][l] = 1000.0 * p + 10.0 * j + l;
  cloth::LaneBlocks out;
  cloth::lane_blocks(terms, out);
  for (int k = 0; k < 3; ++k)
    for (int m = k; m < 3; ++m) {
      const int p = cloth::kPair[k][m];
      for (int l = 0; l < cloth::kLanes; ++l)
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) {
            ASSERT_EQ(out.rows[p][l][3 * r + c], terms.block[p][3 * c + r][l]) << p << " " << l << " " << r << c;
            if (m != k) ASSERT_EQ(out.rows_t[p][l][3 * r + c], terms.block[p][3 * r + c][l]) << p << " " << l;
          }
    }
}
