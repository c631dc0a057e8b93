// The element pass at every instruction level this machine runs (cloth/element_pass,
// element_lanes.hpp, simd_level): the material laws on lanes against the scalar law on every
// branch, each element's terms against evaluate_element, the levels against each other, and the
// pass's kept factors. test_integrator's FusedAssembly holds each level's whole assembled system
// (the scatter and its transposes) against one built from evaluate_element.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "cloth/curve.hpp"
#include "cloth/element_pass.hpp"
#include "cloth/kept_matrix.hpp"
#include "cloth/model.hpp"
#include "support/fixtures.hpp"

using namespace hapticloth;
using cloth::Mat3;
using cloth::SimdLevel;
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

// Eleven random triangles (stretched, compressed, sheared), each with its own corners: a full
// group and a padded one at every width (2, 4 and 8 lanes).
struct Triangles {
  std::vector<cloth::ElementRest> elements;
  std::vector<Vec3> x, v;
};
Triangles random_triangles(int n = 11) {
  std::mt19937 rng(11);
  Triangles t;
  for (int i = 0; i < n; ++i) {
    const auto r = test::random_triangle(rng, i % 3);
    cloth::ElementRest e = r.rest;
    for (int k = 0; k < 3; ++k) {
      e.v[k] = static_cast<int>(t.x.size());
      t.x.push_back(r.x[k]);
      t.v.push_back(r.v[k]);
    }
    t.elements.push_back(e);
  }
  return t;
}

// The level under test, or the test skipped (and says so) when this CPU lacks it.
class ElementPass : public ::testing::TestWithParam<SimdLevel> {
 protected:
  void SetUp() override {
    if (!cloth::runs_here(GetParam()))
      GTEST_SKIP() << cloth::to_string(GetParam()) << ": this CPU lacks its instructions";
  }
  const cloth::ElementKernels& kernels() const { return cloth::element_kernels(GetParam()); }
};

std::string level_name(const ::testing::TestParamInfo<SimdLevel>& p) { return cloth::to_string(p.param); }

}  // namespace

TEST_P(ElementPass, HasTheLanesOfItsLevel) {
  const int expected = GetParam() == SimdLevel::Avx512 ? 8 : GetParam() == SimdLevel::Avx2 ? 4 : 2;
  EXPECT_EQ(kernels().lanes, expected);
  EXPECT_EQ(kernels().level, GetParam());
}

TEST_P(ElementPass, LawOnLanesEqualsTheScalarLawOnEveryBranch) {
  for (const cloth::StrainStressCurve& c : {tensile_law(), shear_law()}) {
    constexpr int n = 75;  // not a multiple of any width: the last vector is partial
    double eps[n], psi[n], s[n], ds[n];
    for (int i = 0; i < n; ++i) eps[i] = -0.3 + 0.6 * i / (n - 1.0);
    kernels().evaluate_law(c, eps, n, psi, s, ds);
    for (int i = 0; i < n; ++i) {
      double psi_ref, s_ref, ds_ref;
      c.evaluate_all(eps[i], psi_ref, s_ref, ds_ref);
      const double tol = 1e-13 * (1.0 + std::abs(s_ref) + std::abs(ds_ref));
      EXPECT_NEAR(psi[i], psi_ref, tol) << "eps " << eps[i];
      EXPECT_NEAR(s[i], s_ref, tol) << "eps " << eps[i];
      EXPECT_NEAR(ds[i], ds_ref, tol) << "eps " << eps[i];
    }
  }
}

// Each element's terms against evaluate_element: right-hand side h (f_k - alpha h sum_l H_kl v_l)
// and blocks alpha^2 h^2 H_kl + alpha h C_kl, with and without viscosity, in both Jacobian
// modes, on stretched, compressed and sheared triangles, in full and padded groups.
TEST_P(ElementPass, TermsEqualTheElementEvaluation) {
  const double h = 0.004, alpha = 0.8;
  const Triangles t = random_triangles();
  for (const double viscosity : {0.0, 0.05})
    for (const auto mode : {cloth::JacobianMode::Spd, cloth::JacobianMode::Exact}) {
      const cloth::Material mat = test::denim(viscosity);
      const cloth::PassInput in{&mat, t.x.data(), t.v.data(), {h, alpha}, viscosity > 0.0,
                                mode == cloth::JacobianMode::Spd};
      std::vector<cloth::ElementTerms> terms(t.elements.size());
      kernels().element_terms(t.elements, in, terms.data());
      for (std::size_t i = 0; i < t.elements.size(); ++i) {
        const auto& e = t.elements[i];
        const Vec3* xp[3] = {&t.x[e.v[0]], &t.x[e.v[1]], &t.x[e.v[2]]};
        const Vec3* vp[3] = {&t.v[e.v[0]], &t.v[e.v[1]], &t.v[e.v[2]]};
        cloth::EvalRequest req;
        req.mode = mode;
        cloth::ElementEval ev;
        cloth::evaluate_element(e, mat, xp, vp, req, ev);
        EXPECT_NEAR(terms[i].energy, ev.energy, 1e-12 * std::abs(ev.energy) + 1e-18);
        for (int k = 0; k < 3; ++k) {
          Vec3 Hv = Vec3::Zero();
          for (int m = 0; m < 3; ++m) Hv += ev.H[k][m] * *vp[m];
          const Vec3 rhs = h * (ev.f[k] - alpha * h * Hv);
          for (int r = 0; r < 3; ++r)
            EXPECT_NEAR(terms[i].rhs[k][r], rhs[r], 1e-12 * (1.0 + rhs.norm())) << "element " << i;
          for (int m = k; m < 3; ++m) {
            const Mat3 ref = alpha * alpha * h * h * ev.H[k][m] + alpha * h * ev.C[k][m];
            const double* blk = terms[i].block[cloth::kPair[k][m]];
            for (int c = 0; c < 3; ++c)
              for (int r = 0; r < 3; ++r)
                EXPECT_NEAR(blk[3 * c + r], ref(r, c), 1e-12 * (1e-9 + ref.norm()))
                    << "element " << i << " block " << k << m;
          }
        }
      }
    }
}

// Every level computes the same numbers as the baseline, to 1e-12 of each quantity's scale (the
// same expressions, lane by lane; a level with FMA may round a contracted product differently).
TEST_P(ElementPass, EqualsTheBaselineLevel) {
  const Triangles t = random_triangles(37);
  const cloth::Material mat = test::denim(0.05);
  const cloth::PassInput in{&mat, t.x.data(), t.v.data(), {0.002, 1.0}, true, true};
  std::vector<cloth::ElementTerms> mine(t.elements.size()), base(t.elements.size());
  kernels().element_terms(t.elements, in, mine.data());
  cloth::element_kernels(SimdLevel::Baseline).element_terms(t.elements, in, base.data());
  double worst = 0.0;
  for (std::size_t i = 0; i < t.elements.size(); ++i) {
    const auto* a = reinterpret_cast<const double*>(&mine[i]);
    const auto* b = reinterpret_cast<const double*>(&base[i]);
    double scale = 0.0;
    for (std::size_t j = 0; j < sizeof(cloth::ElementTerms) / sizeof(double); ++j) scale = std::max(scale, std::abs(b[j]));
    for (std::size_t j = 0; j < sizeof(cloth::ElementTerms) / sizeof(double); ++j)
      worst = std::max(worst, std::abs(a[j] - b[j]) / scale);
  }
  std::printf("%s against baseline: largest difference %.3g of the element's largest term\n",
              cloth::to_string(GetParam()), worst);
  EXPECT_LE(worst, 1e-12);
}

namespace {

// A pass over a 6 x 6 sheet pinned along its top edge, as two parts, into a system laid out as
// the integrator lays it out.
struct SheetPass {
  cloth::Material mat = test::denim();
  cloth::ClothModel model = test::square_cloth(mat, {"top"}, 6, 0.2);
  cloth::SystemPattern sys = cloth::build_pattern(model, 0);
  std::vector<double> A = std::vector<double>(sys.csr.val.size(), 0.0);
  std::vector<double> rhs = std::vector<double>(sys.csr.n, 0.0);
  cloth::KeptMatrix kept{1e-3, 2, sys.csr.n / 3};
  std::unique_ptr<cloth::ElementPass> pass;
  cloth::ClothState s = cloth::rest_state(model);

  explicit SheetPass(const cloth::ElementKernels& k) {
    std::vector<std::vector<int>> parts(2);
    for (int t = 0; t < model.num_triangles(); ++t) parts[t % 2].push_back(t);
    pass = k.make_pass(model.elements, parts);
    for (auto& x : s.x) x *= 1.05;  // every fibre in tension
  }
  // Both parts, the matrix formed as Form says; the elements whose blocks were formed.
  template <class Form>
  int run(Form form) {
    const cloth::PassInput in{&mat, s.x.data(), s.v.data(), {0.002, 1.0}, false, true};
    const cloth::PassTarget out{A.data(), rhs.data(), model.free_index.data(), sys.block_offset.data(),
                                sys.row_stride.data()};
    int formed = 0;
    for (int part = 0; part < 2; ++part) {
      int n = 0;
      pass->run(form, part, in, out, kept, n);
      formed += n;
    }
    return formed;
  }
  // The elements with `vertex` as a corner.
  int around(int vertex) const {
    int n = 0;
    for (const auto& e : model.elements) n += e.v[0] == vertex || e.v[1] == vertex || e.v[2] == vertex;
    return n;
  }
};

}  // namespace

// With the matrix kept, the pass forms the blocks of the elements whose factors moved past the
// tolerance (1e-3 of their largest entry) and no others, and leaves the kept sums equal to the
// matrix formed whole at the new state, to the tolerance; a non-finite factor always moves.
TEST_P(ElementPass, KeptPassFormsOnlyTheElementsThatMoved) {
  SheetPass p(kernels());
  EXPECT_EQ(p.run(cloth::WholeMatrix{}), p.model.num_triangles());
  const int v = p.model.free_vertices[10];
  p.s.x[v] += Vec3(0.0, 0.0, 1e-7);  // far below the tolerance
  EXPECT_EQ(p.run(cloth::KeptChanges{}), 0);
  p.s.x[v] += Vec3(0.0, 0.0, 3e-3);  // a 3 mm dent: its elements' factors move by percents
  EXPECT_EQ(p.run(cloth::KeptChanges{}), p.around(v));
  // The rows marked changed are the free corners of those elements.
  std::vector<int> rows = p.kept.take_changed_rows();
  std::sort(rows.begin(), rows.end());
  std::vector<int> corners;
  for (const auto& e : p.model.elements)
    if (e.v[0] == v || e.v[1] == v || e.v[2] == v)
      for (int k = 0; k < 3; ++k)
        if (p.model.free_index[e.v[k]] >= 0) corners.push_back(p.model.free_index[e.v[k]]);
  std::sort(corners.begin(), corners.end());
  corners.erase(std::unique(corners.begin(), corners.end()), corners.end());
  EXPECT_EQ(rows, corners);
  // Only v moved, so the other elements' factors are exactly the kept ones: the kept sums equal
  // the matrix formed whole at the new state, to rounding.
  SheetPass whole(kernels());
  whole.s = p.s;
  whole.run(cloth::WholeMatrix{});
  double amax = 0.0, diff = 0.0;
  for (std::size_t i = 0; i < p.A.size(); ++i) {
    amax = std::max(amax, std::abs(whole.A[i]));
    diff = std::max(diff, std::abs(p.A[i] - whole.A[i]));
  }
  ASSERT_GT(amax, 0.0);
  EXPECT_LE(diff, 1e-12 * amax);
  p.s.x[v] = Vec3(NAN, 0.0, 0.0);
  EXPECT_EQ(p.run(cloth::KeptChanges{}), p.around(v));
}

INSTANTIATE_TEST_SUITE_P(Levels, ElementPass,
                         ::testing::Values(SimdLevel::Baseline, SimdLevel::Avx2, SimdLevel::Avx512), level_name);

// The names a command line gives, and the levels this binary holds.
TEST(SimdLevel, NamesParseAndTheBestLevelRunsHere) {
  for (SimdLevel l : cloth::built_levels()) EXPECT_EQ(cloth::parse_simd_level(cloth::to_string(l)), l);
  EXPECT_FALSE(cloth::parse_simd_level("avx"));
  EXPECT_FALSE(cloth::parse_simd_level("AVX2"));
  EXPECT_TRUE(cloth::runs_here(SimdLevel::Baseline));
  EXPECT_TRUE(cloth::runs_here(cloth::best_level()));
  std::printf("this CPU runs %s\n", cloth::to_string(cloth::best_level()));
}

// A level the CPU lacks is refused with its name, never run (it would die with SIGILL).
TEST(SimdLevel, ALevelTheCpuLacksIsRefused) {
  for (SimdLevel l : cloth::built_levels()) {
    if (cloth::runs_here(l)) continue;
    try {
      cloth::element_kernels(l);
      ADD_FAILURE() << cloth::to_string(l) << " was not refused";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(cloth::to_string(l)), std::string::npos) << e.what();
    }
    return;
  }
  GTEST_SKIP() << "this CPU runs every level this binary holds";
}
