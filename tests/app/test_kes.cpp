// The simulated Kawabata tests (app/kes) and the static solver under them.
// Requirement: "The simulated tensile and shear tests reproduce the material curve within 0.5%
// of max stress (the element is exact for uniform strain, so what remains is the solver's
// error)."
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include <unistd.h>

#include "app/kes.hpp"
#include "app/toml_file.hpp"
#include "support/fixtures.hpp"

using namespace hapticloth;

namespace {

void expect_reproduces_law(const app::KesResult& r, double max_strain, size_t min_points = 20) {
  ASSERT_TRUE(r.converged);
  ASSERT_GE(r.points.size(), min_points);
  EXPECT_NEAR(r.points.back().strain, max_strain, 1e-3 * max_strain);
  EXPECT_GT(r.max_stress, 0.0);
  EXPECT_LE(r.material_max, 0.005 * r.max_stress);
  EXPECT_LE(r.material_rms, 0.005 * r.max_stress);
  // and the curve is not trivially flat: stress rises with strain
  EXPECT_GT(r.points.back().stress, 0.5 * r.max_stress);
}

}  // namespace

class KesTensile : public ::testing::TestWithParam<app::KesTest> {};

TEST_P(KesTensile, ClampForcePerWidthIsTheMaterialLaw) {
  cloth::Material m = test::denim();
  m.weft.max_strain = 0.3;
  m.warp.max_strain = 0.18;
  const app::KesTest t = GetParam();
  const app::KesResult r = app::run_kes(m, t, {});
  expect_reproduces_law(r, t == app::KesTest::Weft ? 0.3 : 0.18);
  // At 30% the weft law is past its knot at 17%: the simulated test follows the second segment.
  if (t == app::KesTest::Weft) {
    const auto& p = r.points.back();
    EXPECT_NEAR(p.stress, m.weft.stress(0.3), 1e-6 * p.stress);
  }
}

INSTANTIATE_TEST_SUITE_P(Directions, KesTensile,
                         ::testing::Values(app::KesTest::Weft, app::KesTest::Warp));

TEST(KesShear, ShearStressIsTheMaterialLawAndTensionShareIsTakenOut) {
  const cloth::Material m = test::denim();
  app::KesOptions opt;
  const app::KesResult r = app::run_kes(m, app::KesTest::Shear, opt);
  ASSERT_TRUE(r.converged);
  expect_reproduces_law(r, r.points.back().strain);
  // The sweep covers -8..+8 degrees and is odd.
  EXPECT_NEAR(r.points.front().angle, -8.0 * M_PI / 180.0, 1e-12);
  EXPECT_NEAR(r.points.back().angle, 8.0 * M_PI / 180.0, 1e-12);
  EXPECT_NEAR(r.points.front().stress, -r.points.back().stress, 1e-3 * r.max_stress);
  // The tension is held constant, as by the tester's weight.
  // The raw clamp force includes the lateral tension's share, about T tan(angle): 1.38 N/m at
  // 8 degrees, 15% of the denim's shear stress there. The reported stress does not.
  const auto& p = r.points.back();
  const double share = opt.lateral_tension * std::tan(p.angle);
  EXPECT_NEAR(p.clamp_force - p.stress, share, 0.05 * share);
}

TEST(KesShear, CoarserSpecimenStillWithinHalfPercent) {
  app::KesOptions opt;
  opt.cells_per_cm = 1;
  opt.load_steps = 8;
  const app::KesResult r = app::run_kes(test::denim(), app::KesTest::Shear, opt);
  expect_reproduces_law(r, r.points.back().strain, 17);
}

TEST(Kes, RejectsBadOptions) {
  app::KesOptions opt;
  opt.load_steps = 1;
  EXPECT_THROW(app::run_kes(test::denim(), app::KesTest::Weft, opt), std::invalid_argument);
  EXPECT_THROW(app::parse_kes_test("bias"), std::invalid_argument);
}

TEST(Kes, ComparesWithMeasuredPoints) {
  cloth::Material m = test::denim();
  m.weft.max_strain = 0.3;
  app::KesResult r = app::run_kes(m, app::KesTest::Weft, {});
  // Measured points 2% above the law: the comparison reports 2% (of the measured max).
  app::KesMeasured meas;
  for (int i = 0; i <= 20; ++i) {
    const double e = 0.015 * i;
    meas.strain.push_back(e);
    meas.stress.push_back(1.02 * m.weft.stress(e));
  }
  app::compare_measured(r, meas);
  EXPECT_NEAR(r.measured_max / r.measured_max_stress, 0.02 / 1.02, 2e-4);
}

namespace {
std::string write_tmp(const std::string& text) {
  static int n = 0;
  const auto p = std::filesystem::temp_directory_path() /
                 ("hc-kes-" + std::to_string(::getpid()) + "-" + std::to_string(n++) + ".csv");
  std::ofstream(p) << text;
  return p.string();
}

void expect_csv_error(const std::string& text, app::KesTest t, const std::string& where,
                      const std::string& what) {
  const std::string path = write_tmp(text);
  try {
    app::load_measured(path, t);
    ADD_FAILURE() << "no error for:\n" << text;
  } catch (const app::ConfigError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(path + where), std::string::npos) << msg;
    EXPECT_NE(msg.find(what), std::string::npos) << msg;
  }
  std::filesystem::remove(path);
}
}  // namespace

TEST(KesMeasuredCsv, ReadsOneTestAndNamesTheLineOfBadInput) {
  const std::string good = "# fabric: x\ntest,strain,stress\nweft,0,0\nweft,0.1,5\nshear,-0.1,-1\nshear,0.1,1\n";
  const std::string p = write_tmp(good);
  const auto m = app::load_measured(p, app::KesTest::Shear);
  std::filesystem::remove(p);
  ASSERT_EQ(m.strain.size(), 2u);
  EXPECT_DOUBLE_EQ(m.stress[1], 1.0);
  expect_csv_error("strain,stress\n0,0\n", app::KesTest::Weft, ":1:", "header");
  expect_csv_error("test,strain,stress\nweft,0,0\nweft,abc,1\n", app::KesTest::Weft, ":3:", "not a number");
  expect_csv_error("test,strain,stress\nweft,0.1,0\nweft,0.05,1\n", app::KesTest::Weft, ":3:", "increase");
  expect_csv_error("test,strain,stress\nbias,0.1,0\n", app::KesTest::Weft, ":2:", "unknown test");
  expect_csv_error("test,strain,stress\nweft,0.1\n", app::KesTest::Weft, ":2:", "columns");
  expect_csv_error("test,strain,stress\nwarp,0,0\nwarp,0.1,1\n", app::KesTest::Weft, "", "fewer than 2");
}
