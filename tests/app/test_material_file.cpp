// Material files (server/app/material_file): the shipped material, a valid one, and bad ones
// whose errors name the file, the line and the key (support/config_files.hpp).
#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include "app/material_file.hpp"
#include "support/config_files.hpp"

namespace {

using hapticloth::app::format_material;
using hapticloth::app::load_material;
using hapticloth::app::parse_material;
using hapticloth::app::TomlFile;
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

// Every shipped material carries a surface for tactile rendering, with its source, both yarn
// directions, and friction figures (issue 37, point 1).
TEST(ShippedFiles, EveryMaterialHasASurfaceWithItsSource) {
  int n = 0;
  for (const auto& e : std::filesystem::directory_iterator(kSourceDir + "/tools/materials")) {
    if (e.path().extension() != ".toml") continue;
    SCOPED_TRACE(e.path().string());
    const auto m = load_material(e.path().string());
    ++n;
    EXPECT_TRUE(m.surface.present());
    EXPECT_FALSE(m.surface.weft.empty());
    EXPECT_FALSE(m.surface.warp.empty());
    EXPECT_FALSE(m.surface.source.empty());
    EXPECT_GT(m.surface.miu, 0.0);
    EXPECT_GT(m.surface.mmd, 0.0);
    // a yarn every 0.1-2 mm, a relief of micrometres
    for (const auto* p : {&m.surface.weft, &m.surface.warp}) {
      EXPECT_GT(p->period(), 1e-4);
      EXPECT_LT(p->period(), 2e-3);
      EXPECT_GT(p->mean_deviation(), 0.5e-6);
      EXPECT_LT(p->mean_deviation(), 50e-6);
    }
  }
  EXPECT_GE(n, 5);
}

const std::string kSurface =
    "\n"                                           // 15
    "[surface]\n"                                  // 16
    "source = \"a test\"\n"                        // 17
    "miu = 0.2\n"                                  // 18
    "mmd = 0.01\n"                                 // 19
    "[surface.weft]\n"                             // 20
    "yarn_spacing = 0.5e-3\n"                      // 21
    "amplitude = 10e-6\n"                          // 22
    "shape = \"yarn\"\n"                           // 23
    "[surface.warp]\n"                             // 24
    "trace = \"traces/warp.csv\"\n";               // 25

std::string trace_csv(int rows) {
  std::string t = "distance_m,height_m\n# a measured-style trace\n";
  for (int i = 0; i < rows; ++i)
    t += std::to_string(i * 1e-5) + "," + std::to_string(1e-6 * ((i * 7) % 5)) + "\n";
  return t;
}

// A surface from a weave and from a trace CSV (relative to the material file) loads, and is
// written back as it was given.
TEST_F(FilesTest, SurfaceFromAWeaveAndATraceLoadsAndWritesBack) {
  write("traces/warp.csv", trace_csv(50));
  const auto m = load_material(write("m.toml", kMaterial + kSurface));
  EXPECT_EQ(m.surface.source, "a test");
  EXPECT_DOUBLE_EQ(m.surface.miu, 0.2);
  EXPECT_DOUBLE_EQ(m.surface.mmd, 0.01);
  EXPECT_DOUBLE_EQ(m.surface.weft.period(), 0.5e-3);
  EXPECT_NEAR(m.surface.warp.period(), 50e-5, 1e-9);
  EXPECT_EQ(m.surface.warp_source.trace, "traces/warp.csv");
  const auto again = load_material(write("again.toml", format_material(m)));
  EXPECT_EQ(again.surface.weft.samples(), m.surface.weft.samples());
  EXPECT_EQ(again.surface.warp.samples(), m.surface.warp.samples());
  EXPECT_DOUBLE_EQ(again.surface.mmd, 0.01);
  EXPECT_FALSE(load_material(write("plain.toml", kMaterial)).surface.present());
}

TEST_F(FilesTest, BadSurfacesNameTheFileLineAndKey) {
  write("traces/warp.csv", trace_csv(50));
  const std::string good = kMaterial + kSurface;
  const std::vector<BadFile> cases = {
      {"NegativeYarnSpacing", with_line(good, 21, "yarn_spacing = -0.5e-3"), 21, {"key 'surface.weft.yarn_spacing'"}},
      {"HugeAmplitude", with_line(good, 22, "amplitude = 0.01"), 22, {"key 'surface.weft.amplitude'"}},
      {"UnknownShape", with_line(good, 23, "shape = \"twill\""), 23, {"key 'surface.weft.shape'", "twill"}},
      {"FrictionOutOfRange", with_line(good, 18, "miu = -0.1"), 18, {"key 'surface.miu'"}},
      {"UnknownKey", with_line(good, 19, "mdd = 0.01"), 19, {"key 'surface.mdd'", "unknown key"}},
      {"TraceAndWeave", with_line(good, 25, "trace = \"traces/warp.csv\"\nshape = \"sine\""), 25,
       {"key 'surface.warp.trace'", "not both"}},
      {"MissingTrace", with_line(good, 25, "trace = \"traces/none.csv\""), 25,
       {"key 'surface.warp.trace'", "none.csv", "cannot read"}},
      {"MissingSource", with_line(good, 17, ""), 16, {"key 'surface.source'", "missing"}},
  };
  expect_bad_files(cases, "m.toml", [](const std::string& path) { load_material(path); });
  // A bad row of the trace names the material's key, and the CSV's own file and line.
  std::string csv = trace_csv(50);
  csv.replace(csv.find("0.000030,"), 9, "0.0000x0,");
  write("traces/warp.csv", csv);
  const std::string path = write("m.toml", good);
  expect_config_error([&] { load_material(path); }, {path + at_line(25), "warp.csv" + at_line(6), "distance_m,height_m"});
}

}  // namespace
