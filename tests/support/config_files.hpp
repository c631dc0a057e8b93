// Shared by the tests of server/app's file loaders (test_material_file, test_scene_file,
// test_obj_file, test_toml_file). Requirement: "Bad files: a clear error naming the file, line
// and key." Every bad-file case checks that a ConfigError is thrown and that its message
// ("FILE:LINE: key 'a.b': what") contains the file, the line as ":N:" and the key (or the
// specific complaint).
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <initializer_list>
#include <sstream>
#include <string>
#include <vector>

#include <unistd.h>

#include "app/toml_file.hpp"

namespace hapticloth::test {

/// Runs fn, expects a ConfigError, and checks that its message contains every part.
inline void expect_config_error(const std::function<void()>& fn, const std::vector<std::string>& parts) {
  try {
    fn();
  } catch (const app::ConfigError& e) {
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
inline std::string with_line(const std::string& text, int n, const std::string& line) {
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
inline std::string at_line(int n) {
  std::string s(1, ':');  // (not ":" + ..., which trips a false GCC 12 -Wrestrict warning)
  s += std::to_string(n);
  s += ':';
  return s;
}

/// A bad file of a table-driven test: its text, the line the error names and what else the
/// message must contain.
struct BadFile {
  std::string name;
  std::string text;
  int line;
  std::vector<std::string> parts;
};

/// expect_config_error for one case of a table: the message names `path` at c.line, and c.parts.
inline void expect_bad_file(const BadFile& c, const std::string& path, const std::function<void()>& load) {
  SCOPED_TRACE(c.name);
  std::vector<std::string> parts = {path + at_line(c.line)};
  parts.insert(parts.end(), c.parts.begin(), c.parts.end());
  expect_config_error(load, parts);
}

// A valid material; the bad cases replace one line of it.
inline const std::string kMaterial =
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

// A 2 m x 1 m strip in the z = 0 plane: the left unit square as two triangles, the right one
// as a quad (fan-triangulated by the loader). Texture coordinates are half the positions, so
// they give the right directions but not the right lengths. Normals and comments are ignored.
inline const std::string kStripObj =
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

/// A fresh folder per test, removed after it.
class FilesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = std::filesystem::temp_directory_path() /
            ("hapticloth_test_files_" + std::to_string(static_cast<long>(::getpid())));
    dir_ = root_ / ::testing::UnitTest::GetInstance()->current_test_info()->name();
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
    std::filesystem::remove(root_, ec);  // only succeeds once the last test has cleaned up
  }

  /// Writes text to dir_/name (creating folders) and returns the full path.
  std::string write(const std::string& name, const std::string& text) {
    const std::filesystem::path p = dir_ / name;
    std::filesystem::create_directories(p.parent_path());
    std::ofstream out(p);
    out << text;
    out.close();
    EXPECT_TRUE(out) << "cannot write " << p;
    return p.string();
  }

  /// load(path) of a file that is not there throws a ConfigError naming it: "cannot open".
  void expect_cannot_open(const std::string& name, const std::function<void(const std::string&)>& load) {
    const std::string path = (dir_ / name).string();
    expect_config_error([&] { load(path); }, {path, "cannot open"});
  }

  /// Writes each case's text to dir_/name and expects load(path) to throw a ConfigError that
  /// names the path at the case's line, and the case's parts.
  void expect_bad_files(const std::vector<BadFile>& cases, const std::string& name,
                        const std::function<void(const std::string&)>& load) {
    for (const BadFile& c : cases) {
      const std::string path = write(name, c.text);
      expect_bad_file(c, path, [&] { load(path); });
    }
  }

  std::filesystem::path root_, dir_;
};

}  // namespace hapticloth::test
