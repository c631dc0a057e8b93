// Material files (server/app/material_file): the shipped material, a valid one, and bad ones
// whose errors name the file, the line and the key (support/config_files.hpp).
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "app/material_file.hpp"
#include "support/config_files.hpp"

namespace {

using hapticloth::app::load_material;
using namespace hapticloth::test;

const std::string kSourceDir = HAPTICLOTH_SOURCE_DIR;

TEST(ShippedFiles, DenimHandmadeMaterial) {
  const auto m = load_material(kSourceDir + "/tools/materials/denim-handmade.toml");
  EXPECT_EQ(m.name, "11oz black denim (hand-made spline)");
  EXPECT_DOUBLE_EQ(m.areal_density, 0.324);
  ASSERT_EQ(m.weft.segments, 2);
  EXPECT_DOUBLE_EQ(m.weft.knots[0], 0.0);
  EXPECT_DOUBLE_EQ(m.weft.knots[1], 0.17);
  EXPECT_DOUBLE_EQ(m.weft.B[0][1], 399.4);
  EXPECT_DOUBLE_EQ(m.weft.B[1][3], 3378.8);
  EXPECT_FALSE(m.weft.odd);
  EXPECT_EQ(m.warp.segments, 1);
  EXPECT_DOUBLE_EQ(m.warp.B[0][1], 2003.9);
  EXPECT_FALSE(m.warp.odd);
  EXPECT_EQ(m.shear.segments, 1);
  EXPECT_TRUE(m.shear.odd);
  const double s = m.shear.stress(0.05);
  EXPECT_GT(s, 0.0);
  EXPECT_EQ(m.shear.stress(-0.05), -s);
}

TEST_F(FilesTest, ValidMaterialLoads) {
  const auto m = load_material(write("m.toml", kMaterial));
  EXPECT_EQ(m.name, "test cloth");
  EXPECT_DOUBLE_EQ(m.areal_density, 0.3);
  EXPECT_DOUBLE_EQ(m.weft.B[0][1], 100.0);
  EXPECT_DOUBLE_EQ(m.shear.B[0][1], 10.0);
  EXPECT_TRUE(m.shear.odd);
}

TEST_F(FilesTest, BadMaterialsNameTheFileLineAndKey) {
  // Written with dotted keys: the implicit [weft] table takes the line of its first key.
  const std::string dotted =
      "areal_density = 0.3\n"                                                   // 1
      "weft.knots = [0.0, 0.2, 0.1]\n"                                          // 2
      "weft.B = [[0.0, 100.0, 0.0, 0.0], [0.0, 0.0, 10.0, 0.0], [0.0, 0.0, 10.0, 0.0]]\n"
      "warp.knots = [0.0]\n"
      "warp.B = [[0.0, 100.0, 0.0, 0.0]]\n"
      "shear.knots = [0.0]\n"
      "shear.B = [[0.0, 10.0, 0.0, 0.0]]\n";
  const std::string two_knots = with_line(kMaterial, 5, "knots = [0.0, 0.17]");
  const std::vector<BadFile> cases = {
      // A missing key has no line of its own: the error points at the enclosing (root) table.
      {"MissingArealDensity", with_line(kMaterial, 2, "# no density"), 1, {"key 'areal_density'", "missing"}},
      {"NegativeArealDensity", with_line(kMaterial, 2, "areal_density = -1"), 2,
       {"key 'areal_density'", "must be > 0"}},
      {"ArealDensityWrongType", with_line(kMaterial, 2, "areal_density = \"heavy\""), 2,
       {"key 'areal_density'", "expected a number"}},
      {"KnotsNotIncreasing", dotted, 2,
       {"key 'weft'", "knots must be finite and strictly increasing", "knot 2 = 0.1"}},
      {"TooManyKnots", with_line(kMaterial, 9, "knots = [0.0, 0.1, 0.2, 0.3]"), 9,
       {"key 'warp.knots'", "expected 1 to 3 numbers, got 4"}},
      {"BRowCountDoesNotMatchKnots", two_knots, 6, {"key 'weft.B'", "one row per knot (2), got 1"}},
      {"BRowWrongLength", with_line(kMaterial, 10, "B = [[0.0, 100.0, 0.0]]"), 10,
       {"key 'warp.B[0]'", "expected 4 numbers"}},
      {"BreaksC1AtInnerKnot", with_line(two_knots, 6, "B = [[0.0, 100.0, 0.0, 0.0], [5.0, 0.0, 0.0, 0.0]]"), 4,
       {"key 'weft'", "B[1][0]", "C1"}},
      {"ShearNotOdd", with_line(kMaterial, 14, "B = [[1.0, 10.0, 0.0, 0.0]]"), 12,
       {"key 'shear'", "odd", "B[0][0] = 0"}},
      // sigma = 100 eps - 2000 eps^2: the tangent 100 - 4000 eps is negative past 2.5% strain.
      {"DecreasingCurve", with_line(kMaterial, 6, "B = [[0, 100, -2000, 0]]"), 4,
       {"key 'weft'", "tangent d sigma/d eps is negative"}},
      {"UnknownKey", with_line(kMaterial, 7, "viscosty = 0.1"), 7,
       {"key 'weft.viscosty'", "unknown key", "viscosity"}},
      {"MissingCurve", with_line(with_line(with_line(kMaterial, 12, ""), 13, ""), 14, ""), 1,
       {"key 'shear'", "missing"}},
      {"InvalidToml", with_line(kMaterial, 9, "knots = = [0.0]"), 9, {"invalid TOML"}},
  };
  const auto load = [](const std::string& path) { load_material(path); };
  expect_bad_files(cases, "m.toml", load);
  expect_cannot_open("no_such_material.toml", load);
}

}  // namespace
