// File loaders of server/app: material files, scene files and OBJ meshes.
// Requirement: "Bad files: a clear error naming the file, line and key." Every bad-file case
// checks that a ConfigError is thrown and that its message ("FILE:LINE: key 'a.b': what")
// contains the file, the line as ":N:" and the key (or the specific complaint).

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <initializer_list>
#include <sstream>
#include <string>

#include <unistd.h>

#include "app/material_file.hpp"
#include "app/obj_file.hpp"
#include "app/scene_file.hpp"
#include "app/toml_file.hpp"
#include "cloth/element.hpp"
#include "cloth/model.hpp"

namespace {

namespace fs = std::filesystem;
using hapticloth::app::ConfigError;
using hapticloth::app::load_material;
using hapticloth::app::load_obj;
using hapticloth::app::load_scene;

const std::string kSourceDir = HAPTICLOTH_SOURCE_DIR;

/// Runs fn, expects a ConfigError, and checks that its message contains every part.
void expect_config_error(const std::function<void()>& fn,
                         std::initializer_list<std::string> parts) {
  try {
    fn();
  } catch (const ConfigError& e) {
    const std::string msg = e.what();
    for (const auto& p : parts)
      if (msg.find(p) == std::string::npos)
        ADD_FAILURE() << "the message lacks \"" << p << "\"\n  message: " << msg;
    return;
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected a ConfigError, got another exception: " << e.what();
    return;
  }
  ADD_FAILURE() << "expected a ConfigError, nothing was thrown";
}

/// The text with its 1-based line `n` replaced by `line` (keeps every other line number).
std::string with_line(const std::string& text, int n, const std::string& line) {
  std::istringstream in(text);
  std::ostringstream out;
  std::string l;
  int i = 0;
  bool replaced = false;
  while (std::getline(in, l)) {
    ++i;
    if (i == n) {
      out << line << "\n";
      replaced = true;
    } else {
      out << l << "\n";
    }
  }
  EXPECT_TRUE(replaced) << "the text has no line " << n;
  return out.str();
}

/// ":N:" as it appears in "FILE:N: ..." messages.
std::string at_line(int n) {
  std::string s(1, ':');  // (not ":" + ..., which trips a false GCC 12 -Wrestrict warning)
  s += std::to_string(n);
  s += ':';
  return s;
}

// A valid material; the bad cases below replace one line of it.
const std::string kMaterial =
    "name = \"test cloth\"\n"                        // 1
    "areal_density = 0.3\n"                          // 2
    "\n"                                             // 3
    "[weft]\n"                                       // 4
    "knots = [0.0]\n"                                // 5
    "B = [[0.0, 100.0, 0.0, 0.0]]\n"                 // 6
    "\n"                                             // 7
    "[warp]\n"                                       // 8
    "knots = [0.0]\n"                                // 9
    "B = [[0.0, 100.0, 0.0, 0.0]]\n"                 // 10
    "\n"                                             // 11
    "[shear]\n"                                      // 12
    "knots = [0.0]\n"                                // 13
    "B = [[0.0, 10.0, 0.0, 0.0]]\n";                 // 14

// A valid scene next to the material "cloth.toml"; the bad cases replace one line of it.
const std::string kScene =
    "name = \"test scene\"\n"                        // 1
    "material = \"cloth.toml\"\n"                    // 2
    "\n"                                             // 3
    "[mesh]\n"                                       // 4
    "type = \"grid\"\n"                              // 5
    "size = [1.0, 1.0]\n"                            // 6
    "resolution = [4, 4]\n"                          // 7
    "\n"                                             // 8
    "[pins]\n"                                       // 9
    "edges = [\"top\"]\n"                            // 10
    "\n"                                             // 11
    "[integrator]\n"                                 // 12
    "dt = 0.01\n"                                    // 13
    "alpha = 1.0\n"                                  // 14
    "solver = \"pcg\"\n";                            // 15

// A 2 m x 1 m strip in the z = 0 plane: the left unit square as two triangles, the right one
// as a quad (fan-triangulated by the loader). Texture coordinates are half the positions, so
// they give the right directions but not the right lengths. Normals and comments are ignored.
const std::string kStripObj =
    "# strip\n"                                      // 1
    "v 0 0 0\n"                                      // 2   vertex 1
    "v 1 0 0\n"                                      // 3   vertex 2
    "v 1 1 0\n"                                      // 4   vertex 3
    "v 0 1 0\n"                                      // 5   vertex 4
    "v 2 0 0\n"                                      // 6   vertex 5
    "v 2 1 0\n"                                      // 7   vertex 6
    "vt 0 0\n"                                       // 8
    "vt 0.5 0\n"                                     // 9
    "vt 0.5 0.5\n"                                   // 10
    "vt 0 0.5\n"                                     // 11
    "vt 1 0\n"                                       // 12
    "vt 1 0.5\n"                                     // 13
    "vn 0 0 1\n"                                     // 14
    "f 1/1/1 2/2/1 3/3/1\n"                          // 15
    "f 1/1/1 3/3/1 4/4/1\n"                          // 16
    "f 2/2/1 5/5/1 6/6/1 3/3/1\n";                   // 17

class FilesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() /
            ("hapticloth_test_files_" + std::to_string(static_cast<long>(::getpid())));
    dir_ = root_ / ::testing::UnitTest::GetInstance()->current_test_info()->name();
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
    fs::remove(root_, ec);  // only succeeds once the last test has cleaned up
  }

  /// Writes text to dir_/name (creating folders) and returns the full path.
  std::string write(const std::string& name, const std::string& text) {
    const fs::path p = dir_ / name;
    fs::create_directories(p.parent_path());
    std::ofstream out(p);
    out << text;
    out.close();
    EXPECT_TRUE(out) << "cannot write " << p;
    return p.string();
  }

  /// Writes the material and the scene and loads the scene.
  hapticloth::app::Scene scene(const std::string& scene_text) {
    write("cloth.toml", kMaterial);
    return load_scene(write("scene.toml", scene_text));
  }

  fs::path root_, dir_;
};

// ---------------------------------------------------------------------------------------------
// Shipped files

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

TEST(ShippedFiles, HangingSquareScene) {
  const auto s = load_scene(kSourceDir + "/tools/scenes/hanging_square.toml");
  EXPECT_EQ(s.name, "hanging_square");
  EXPECT_EQ(s.mesh.triangles.size(), 968u);
  EXPECT_EQ(s.mesh.positions.size(), 529u);
  EXPECT_EQ(s.mesh.weave_uv.size(), 968u);
  ASSERT_EQ(s.pins.size(), 23u);
  for (int v : s.pins) {
    ASSERT_GE(v, 0);
    ASSERT_LT(v, 529);
    EXPECT_NEAR(s.mesh.positions[v].y(), 0.25, 1e-12) << "pinned vertex " << v;
  }
  int top = 0;
  for (const auto& p : s.mesh.positions) top += std::abs(p.y() - 0.25) < 1e-12;
  EXPECT_EQ(top, 23) << "every vertex of the top edge is pinned";
  EXPECT_DOUBLE_EQ(s.integrator.dt, 0.001);
  EXPECT_DOUBLE_EQ(s.integrator.alpha, 1.0);
  EXPECT_EQ(s.solver, "pcg");
  EXPECT_DOUBLE_EQ(s.material.areal_density, 0.324);
  EXPECT_NE(s.material_path.find("denim-handmade.toml"), std::string::npos);
}

// ---------------------------------------------------------------------------------------------
// Materials

TEST_F(FilesTest, ValidMaterialLoads) {
  const auto m = load_material(write("m.toml", kMaterial));
  EXPECT_EQ(m.name, "test cloth");
  EXPECT_DOUBLE_EQ(m.areal_density, 0.3);
  EXPECT_DOUBLE_EQ(m.weft.B[0][1], 100.0);
  EXPECT_DOUBLE_EQ(m.shear.B[0][1], 10.0);
  EXPECT_TRUE(m.shear.odd);
}

TEST_F(FilesTest, MaterialMissingArealDensity) {
  const auto path = write("m.toml", with_line(kMaterial, 2, "# no density"));
  // A missing key has no line of its own: the error points at the enclosing (root) table.
  expect_config_error([&] { load_material(path); },
                      {path, at_line(1), "key 'areal_density'", "missing"});
}

TEST_F(FilesTest, MaterialNegativeArealDensity) {
  const auto path = write("m.toml", with_line(kMaterial, 2, "areal_density = -1"));
  expect_config_error([&] { load_material(path); },
                      {path, at_line(2), "key 'areal_density'", "must be > 0"});
}

TEST_F(FilesTest, MaterialArealDensityWrongType) {
  const auto path = write("m.toml", with_line(kMaterial, 2, "areal_density = \"heavy\""));
  expect_config_error([&] { load_material(path); },
                      {path, at_line(2), "key 'areal_density'", "expected a number"});
}

TEST_F(FilesTest, MaterialKnotsNotIncreasing) {
  // Written with dotted keys: the implicit [weft] table takes the line of its first key.
  const std::string text =
      "areal_density = 0.3\n"                                                   // 1
      "weft.knots = [0.0, 0.2, 0.1]\n"                                          // 2
      "weft.B = [[0.0, 100.0, 0.0, 0.0], [0.0, 0.0, 10.0, 0.0], [0.0, 0.0, 10.0, 0.0]]\n"
      "warp.knots = [0.0]\n"
      "warp.B = [[0.0, 100.0, 0.0, 0.0]]\n"
      "shear.knots = [0.0]\n"
      "shear.B = [[0.0, 10.0, 0.0, 0.0]]\n";
  const auto path = write("m.toml", text);
  expect_config_error([&] { load_material(path); },
                      {path, at_line(2), "key 'weft'", "knots must be finite and strictly increasing",
                       "knot 2 = 0.1"});
}

TEST_F(FilesTest, MaterialTooManyKnots) {
  const auto path = write("m.toml", with_line(kMaterial, 9, "knots = [0.0, 0.1, 0.2, 0.3]"));
  expect_config_error([&] { load_material(path); },
                      {path, at_line(9), "key 'warp.knots'", "expected 1 to 3 numbers, got 4"});
}

TEST_F(FilesTest, MaterialBRowCountDoesNotMatchKnots) {
  const auto path = write("m.toml", with_line(kMaterial, 5, "knots = [0.0, 0.17]"));
  expect_config_error([&] { load_material(path); },
                      {path, at_line(6), "key 'weft.B'", "one row per knot (2), got 1"});
}

TEST_F(FilesTest, MaterialBRowWrongLength) {
  const auto path = write("m.toml", with_line(kMaterial, 10, "B = [[0.0, 100.0, 0.0]]"));
  expect_config_error([&] { load_material(path); },
                      {path, at_line(10), "key 'warp.B[0]'", "expected 4 numbers"});
}

TEST_F(FilesTest, MaterialBreaksC1AtInnerKnot) {
  auto text = with_line(kMaterial, 5, "knots = [0.0, 0.17]");
  text = with_line(text, 6, "B = [[0.0, 100.0, 0.0, 0.0], [5.0, 0.0, 0.0, 0.0]]");
  const auto path = write("m.toml", text);
  expect_config_error([&] { load_material(path); },
                      {path, at_line(4), "key 'weft'", "B[1][0]", "C1"});
}

TEST_F(FilesTest, MaterialShearNotOdd) {
  const auto path = write("m.toml", with_line(kMaterial, 14, "B = [[1.0, 10.0, 0.0, 0.0]]"));
  expect_config_error([&] { load_material(path); },
                      {path, at_line(12), "key 'shear'", "odd", "B[0][0] = 0"});
}

TEST_F(FilesTest, MaterialDecreasingCurve) {
  // sigma = 100 eps - 2000 eps^2: the tangent 100 - 4000 eps is negative past 2.5% strain.
  const auto path = write("m.toml", with_line(kMaterial, 6, "B = [[0, 100, -2000, 0]]"));
  expect_config_error([&] { load_material(path); },
                      {path, at_line(4), "key 'weft'", "tangent d sigma/d eps is negative"});
}

TEST_F(FilesTest, MaterialUnknownKey) {
  const auto path = write("m.toml", with_line(kMaterial, 7, "viscosty = 0.1"));
  expect_config_error([&] { load_material(path); },
                      {path, at_line(7), "key 'weft.viscosty'", "unknown key", "viscosity"});
}

TEST_F(FilesTest, MaterialMissingCurve) {
  auto text = with_line(kMaterial, 12, "");
  text = with_line(text, 13, "");
  text = with_line(text, 14, "");
  const auto path = write("m.toml", text);
  expect_config_error([&] { load_material(path); }, {path, at_line(1), "key 'shear'", "missing"});
}

TEST_F(FilesTest, MaterialInvalidToml) {
  const auto path = write("m.toml", with_line(kMaterial, 9, "knots = = [0.0]"));
  expect_config_error([&] { load_material(path); }, {path, at_line(9), "invalid TOML"});
}

TEST_F(FilesTest, MaterialMissingFile) {
  const std::string path = (dir_ / "no_such_material.toml").string();
  expect_config_error([&] { load_material(path); }, {path, "cannot open"});
}

// ---------------------------------------------------------------------------------------------
// Scenes

TEST_F(FilesTest, ValidSceneLoads) {
  const auto s = scene(kScene);
  EXPECT_EQ(s.name, "test scene");
  EXPECT_EQ(s.mesh.triangles.size(), 32u);
  EXPECT_EQ(s.mesh.positions.size(), 25u);
  EXPECT_EQ(s.pins.size(), 5u);
  EXPECT_DOUBLE_EQ(s.integrator.dt, 0.01);
  EXPECT_DOUBLE_EQ(s.material.areal_density, 0.3);
  EXPECT_EQ(s.material_path, (dir_ / "cloth.toml").string());
}

TEST_F(FilesTest, SceneUnknownTopLevelKey) {
  const auto path = (dir_ / "scene.toml").string();
  expect_config_error([&] { scene(with_line(kScene, 3, "gravity = [0.0, 0.0, -9.81]")); },
                      {path, at_line(3), "key 'gravity'", "unknown key", "physics"});
}

// Direct coupling solves the fingertip spheres with the cloth: the local patch's kernel keys are
// rejected there, with what replaced them.
TEST_F(FilesTest, SceneKernelKeyWithDirectCoupling) {
  const auto path = (dir_ / "scene.toml").string();
  expect_config_error(
      [&] { scene(kScene + "\n[haptics]\nlocal_patch = \"off\"\nkernel_radius = 0.02\n"); },
      {path, at_line(19), "haptics.kernel_radius", "local_patch = \"on\"", "contact_stiffness"});
  expect_config_error(
      [&] { scene(kScene + "\n[haptics]\nlocal_patch = \"off\"\ncontact_stiffness = -1\n"); },
      {path, at_line(19), "haptics.contact_stiffness", "must be > 0"});
  EXPECT_NO_THROW(scene(kScene + "\n[haptics]\nlocal_patch = \"on\"\nlocal_model = \"patch\"\nkernel_radius = 0.02\n"));
  expect_config_error(
      [&] { scene(kScene + "\n[haptics]\nlocal_patch = \"on\"\nkernel_radius = 0.02\n"); },
      {path, at_line(19), "haptics.kernel_radius", "local_model = \"patch\""});
  expect_config_error(
      [&] { scene(kScene + "\n[haptics]\nlocal_model = \"springs\"\n"); },
      {path, at_line(18), "haptics.local_model", "\"response\" or \"patch\""});
}

TEST_F(FilesTest, SceneUnknownDeviceDriver) {
  const auto path = (dir_ / "scene.toml").string();
  expect_config_error([&] { scene(kScene + "\n[device]\ndriver = \"phantom\"\n"); },
                      {path, at_line(18), "key 'device.driver'", "unknown driver 'phantom'", "mock"});
}

TEST_F(FilesTest, SceneAlphaOutOfRange) {
  const auto path = (dir_ / "scene.toml").string();
  expect_config_error([&] { scene(with_line(kScene, 14, "alpha = 0.3")); },
                      {path, at_line(14), "key 'integrator.alpha'", "[0.5, 1]"});
}

TEST_F(FilesTest, SceneZeroTimeStep) {
  const auto path = (dir_ / "scene.toml").string();
  expect_config_error([&] { scene(with_line(kScene, 13, "dt = 0")); },
                      {path, at_line(13), "key 'integrator.dt'", "must be > 0"});
}

TEST_F(FilesTest, SceneUnknownSolver) {
  const auto path = (dir_ / "scene.toml").string();
  expect_config_error([&] { scene(with_line(kScene, 15, "solver = \"lu\"")); },
                      {path, at_line(15), "key 'integrator.solver'", "\"pcg\""});
}

TEST_F(FilesTest, SceneUnknownMeshType) {
  const auto path = (dir_ / "scene.toml").string();
  expect_config_error([&] { scene(with_line(kScene, 5, "type = \"sphere\"")); },
                      {path, at_line(5), "key 'mesh.type'", "\"grid\" or \"obj\""});
}

TEST_F(FilesTest, SceneZeroResolution) {
  const auto path = (dir_ / "scene.toml").string();
  expect_config_error([&] { scene(with_line(kScene, 7, "resolution = [0, 5]")); },
                      {path, at_line(7), "key 'mesh.resolution'", "[1, 2000]"});
}

TEST_F(FilesTest, SceneUnknownPinEdge) {
  const auto path = (dir_ / "scene.toml").string();
  expect_config_error([&] { scene(with_line(kScene, 10, "edges = [\"middle\"]")); },
                      {path, at_line(10), "key 'pins.edges'", "'middle'"});
}

TEST_F(FilesTest, ScenePinVertexOutOfRange) {
  const auto path = (dir_ / "scene.toml").string();
  expect_config_error([&] { scene(with_line(kScene, 10, "vertices = [100000]")); },
                      {path, at_line(10), "key 'pins.vertices'", "100000", "[0, 25)"});
}

TEST_F(FilesTest, SceneMissingMaterialFile) {
  const auto material = (dir_ / "missing.toml").string();
  const auto path = (dir_ / "scene.toml").string();
  expect_config_error([&] { scene(with_line(kScene, 2, "material = \"missing.toml\"")); },
                      {path + at_line(2), "key 'material'", material, "cannot open"});
}

TEST_F(FilesTest, SceneErrorInMaterialNamesTheMaterialFile) {
  // The scene is fine; the error is in the material it refers to.
  write("bad_cloth.toml", with_line(kMaterial, 2, "areal_density = -1"));
  const auto material = (dir_ / "bad_cloth.toml").string();
  expect_config_error([&] { scene(with_line(kScene, 2, "material = \"bad_cloth.toml\"")); },
                      {material + at_line(2), "key 'areal_density'"});
}

// ---------------------------------------------------------------------------------------------
// OBJ meshes

// The strip scene lives in a sub-folder; its paths are relative to that folder.
std::string obj_scene(const std::string& weave_lines) {
  return "material = \"../cloth.toml\"\n"
         "[mesh]\n"
         "type = \"obj\"\n"
         "path = \"../meshes/strip.obj\"\n" +
         weave_lines;
}

TEST_F(FilesTest, ObjFanTriangulatesPolygons) {
  const auto obj = load_obj(write("meshes/strip.obj", kStripObj));
  EXPECT_EQ(obj.positions.size(), 6u);
  EXPECT_EQ(obj.texcoords.size(), 6u);
  ASSERT_EQ(obj.triangles.size(), 4u);
  // The quad 2 5 6 3 (1-based) becomes the fan (2 5 6), (2 6 3), 0-based below.
  EXPECT_EQ(obj.triangles[2], (std::array<int, 3>{1, 4, 5}));
  EXPECT_EQ(obj.triangles[3], (std::array<int, 3>{1, 5, 2}));
  EXPECT_EQ(obj.triangle_texcoords[3], (std::array<int, 3>{1, 5, 2}));
}

TEST_F(FilesTest, ObjSceneUvDirections) {
  write("cloth.toml", kMaterial);
  write("meshes/strip.obj", kStripObj);
  const auto path = write("scenes/strip.toml", obj_scene("weave = \"uv-directions\"\n"));
  const auto s = load_scene(path);
  EXPECT_EQ(s.mesh.triangles.size(), 4u);
  EXPECT_EQ(s.mesh.positions.size(), 6u);
  EXPECT_EQ(s.material_path, (dir_ / "cloth.toml").string());

  // Only directions come from the texture: lengths are those of the 3D rest shape.
  const auto model = hapticloth::app::build_model(s);
  ASSERT_EQ(model.num_triangles(), 4);
  EXPECT_NEAR(model.total_area, 2.0, 1e-12);
  for (const auto& e : model.elements) {
    const auto& x = model.rest_positions;
    const auto eps = hapticloth::cloth::element_strains(e, x[e.v[0]], x[e.v[1]], x[e.v[2]]);
    EXPECT_NEAR(eps.uu, 0.0, 1e-12);
    EXPECT_NEAR(eps.vv, 0.0, 1e-12);
    EXPECT_NEAR(eps.uv, 0.0, 1e-12);
    // The weft runs along increasing texture u, here +x.
    const hapticloth::cloth::Vec3 U =
        e.ru[0] * x[e.v[0]] + e.ru[1] * x[e.v[1]] + e.ru[2] * x[e.v[2]];
    EXPECT_NEAR(U.x(), 1.0, 1e-12);
  }
}

TEST_F(FilesTest, ObjSceneUvMetric) {
  write("cloth.toml", kMaterial);
  write("meshes/strip.obj", kStripObj);

  // Texture coordinates are half the positions: uv_scale = 2 makes them metres of cloth.
  {
    const auto s = load_scene(
        write("scenes/strip.toml", obj_scene("weave = \"uv-metric\"\nuv_scale = 2.0\n")));
    const auto model = hapticloth::app::build_model(s);
    ASSERT_EQ(model.num_triangles(), 4);
    EXPECT_NEAR(model.total_area, 2.0, 1e-12);
    for (const auto& e : model.elements) {
      const auto& x = model.rest_positions;
      const auto eps = hapticloth::cloth::element_strains(e, x[e.v[0]], x[e.v[1]], x[e.v[2]]);
      EXPECT_NEAR(eps.uu, 0.0, 1e-12);
      EXPECT_NEAR(eps.vv, 0.0, 1e-12);
      EXPECT_NEAR(eps.uv, 0.0, 1e-12);
    }
  }
  // Without the scale the cloth is half as long as the mesh: it starts stretched by 100%.
  {
    const auto s =
        load_scene(write("scenes/strip.toml", obj_scene("weave = \"uv-metric\"\n")));
    const auto model = hapticloth::app::build_model(s);
    EXPECT_NEAR(model.total_area, 0.5, 1e-12);
    for (const auto& e : model.elements) {
      const auto& x = model.rest_positions;
      const auto eps = hapticloth::cloth::element_strains(e, x[e.v[0]], x[e.v[1]], x[e.v[2]]);
      EXPECT_NEAR(eps.uu, 1.0, 1e-12);
      EXPECT_NEAR(eps.vv, 1.0, 1e-12);
    }
  }
}

TEST_F(FilesTest, ObjSceneBadWeave) {
  write("cloth.toml", kMaterial);
  write("meshes/strip.obj", kStripObj);
  const auto path = write("scenes/strip.toml", obj_scene("weave = \"uv\"\n"));
  expect_config_error([&] { load_scene(path); }, {path, at_line(5), "key 'mesh.weave'"});
}

TEST_F(FilesTest, ObjFaceIndexOutOfRange) {
  const auto path = write("meshes/strip.obj", with_line(kStripObj, 16, "f 1/1 3/3 7/4"));
  expect_config_error([&] { load_obj(path); },
                      {path + at_line(16), "face vertex index 7 out of range"});
}

TEST_F(FilesTest, ObjTextureIndexOutOfRange) {
  const auto path = write("meshes/strip.obj", with_line(kStripObj, 15, "f 1/1 2/9 3/3"));
  expect_config_error([&] { load_obj(path); },
                      {path + at_line(15), "face texture index 9 out of range"});
}

TEST_F(FilesTest, ObjFaceWithoutTextureCoordinates) {
  write("cloth.toml", kMaterial);
  const auto obj = write("meshes/strip.obj", with_line(kStripObj, 16, "f 1 3 4"));
  const auto path = write("scenes/strip.toml", obj_scene(""));
  expect_config_error([&] { load_scene(path); }, {obj + at_line(16), "face", "no texture coordinates"});
}

TEST_F(FilesTest, ObjVertexWithTwoNumbers) {
  const auto path = write("meshes/strip.obj", with_line(kStripObj, 4, "v 1 1"));
  expect_config_error([&] { load_obj(path); },
                      {path + at_line(4), "vertex needs three finite numbers"});
}

TEST_F(FilesTest, ObjMissingFile) {
  write("cloth.toml", kMaterial);
  const auto path = write("scenes/strip.toml", obj_scene(""));
  expect_config_error([&] { load_scene(path); }, {(dir_ / "meshes/strip.obj").string(), "cannot open"});
}

}  // namespace
