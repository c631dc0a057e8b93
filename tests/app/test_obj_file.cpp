// Wavefront OBJ meshes (server/app/obj_file): polygons fan-triangulated, and malformed records
// named by file and line (support/config_files.hpp).
#include <gtest/gtest.h>

#include <array>
#include <string>
#include <vector>

#include "app/obj_file.hpp"
#include "support/config_files.hpp"

namespace {

using hapticloth::app::load_obj;
using namespace hapticloth::test;

TEST_F(FilesTest, ObjFanTriangulatesPolygons) {
  const auto obj = load_obj(write("meshes/strip.obj", kStripObj));
  EXPECT_EQ(obj.positions.size(), 6u);
  EXPECT_EQ(obj.texcoords.size(), 6u);
  ASSERT_EQ(obj.triangles.size(), 4u);
  // The quad 2 5 6 3 (1-based) becomes the fan (2 5 6), (2 6 3), 0-based below.
  EXPECT_EQ(obj.triangles[2], (std::array<int, 3>{1, 4, 5}));
  EXPECT_EQ(obj.triangles[3], (std::array<int, 3>{1, 5, 2}));
  EXPECT_EQ(obj.triangle_texcoords[3], (std::array<int, 3>{1, 5, 2}));
  EXPECT_EQ(obj.triangle_lines[3], 17);
}

TEST_F(FilesTest, BadObjRecordsNameTheFileAndLine) {
  const std::vector<BadFile> cases = {
      {"FaceIndexOutOfRange", with_line(kStripObj, 16, "f 1/1 3/3 7/4"), 16,
       {"face vertex index 7 out of range"}},
      {"TextureIndexOutOfRange", with_line(kStripObj, 15, "f 1/1 2/9 3/3"), 15,
       {"face texture index 9 out of range"}},
      {"VertexWithTwoNumbers", with_line(kStripObj, 4, "v 1 1"), 4, {"vertex needs three finite numbers"}},
  };
  const auto load = [](const std::string& path) { load_obj(path); };
  expect_bad_files(cases, "meshes/strip.obj", load);
  expect_cannot_open("no_such_mesh.obj", load);
}

}  // namespace
