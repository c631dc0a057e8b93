// Fingertip trajectories (devices/mock/trajectory): TOML primitives, CSV keyframes, the speed
// check, and bad files named by file, line and field.
#include <gtest/gtest.h>

#include <filesystem>
#include <stdexcept>
#include <string>

#include "mock/trajectory.hpp"
#include "support/temp_files.hpp"

using namespace hapticloth::devices;
using hapticloth::test::write_temp;
namespace fs = std::filesystem;

namespace {
void expect_error(const std::string& text, const std::string& ext, const std::string& where,
                  const std::string& what) {
  const std::string p = write_temp(text, ext);
  try {
    load_trajectory(p, 2);
    ADD_FAILURE() << "no error for:\n" << text;
  } catch (const std::invalid_argument& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find(p + where), std::string::npos) << m;
    EXPECT_NE(m.find(what), std::string::npos) << m;
  }
  fs::remove(p);
}
}  // namespace

TEST(Trajectory, PrimitivesMoveTheFingersAsScripted) {
  const std::string p = write_temp(R"(
[start]
finger0 = [-0.02, 0.0, 0.03]
finger1 = [0.02, 0.0, 0.03]
[[step]]
primitive = "approach"
distance = 0.03
duration = 1.0
[[step]]
primitive = "press"
depth = 0.004
duration = 0.5
[[step]]
primitive = "stroke"
direction = [0, 1, 0]
distance = 0.02
duration = 0.5
[[step]]
primitive = "pinch"
gap = 0.016
duration = 0.5
[[step]]
primitive = "lift"
height = 0.01
duration = 0.5
[[step]]
primitive = "release"
duration = 0.5
)", ".toml");
  const Trajectory tr = load_trajectory(p, 2);
  fs::remove(p);
  Vec3 x, v;
  tr.evaluate(0, 0.5, x, v);  // half-way through the approach
  EXPECT_TRUE(x.isApprox(Vec3(-0.02, 0, 0.015), 1e-12));
  EXPECT_TRUE(v.isApprox(Vec3(0, 0, -0.03), 1e-12));
  tr.evaluate(1, 1.5, x, v);  // end of press
  EXPECT_TRUE(x.isApprox(Vec3(0.02, 0, -0.004), 1e-12));
  tr.evaluate(0, 2.0, x, v);  // end of stroke
  EXPECT_NEAR(x.y(), 0.02, 1e-12);
  Vec3 a, b;
  tr.evaluate(0, 2.5, a, v);  // end of pinch
  tr.evaluate(1, 2.5, b, v);
  EXPECT_NEAR((b - a).norm(), 0.016, 1e-12);
  tr.evaluate(0, 3.0, x, v);  // end of lift
  EXPECT_NEAR(x.z(), 0.006, 1e-12);
  tr.evaluate(0, 3.5, a, v);
  tr.evaluate(1, 3.5, b, v);
  EXPECT_NEAR((b - a).norm(), 0.04, 1e-12);  // released
  EXPECT_DOUBLE_EQ(tr.duration(), 3.5);
  tr.evaluate(0, 10.0, x, v);  // after the end: at rest where it ended
  EXPECT_EQ(v, Vec3::Zero());
}

TEST(Trajectory, CsvKeyframesInterpolate) {
  const std::string p = write_temp("time,finger,x,y,z\n0,0,0,0,0\n1,0,0.01,0,0\n0,1,0,0,0\n2,1,0,0.02,0\n", ".csv");
  const Trajectory tr = load_trajectory(p, 2);
  fs::remove(p);
  Vec3 x, v;
  tr.evaluate(1, 1.0, x, v);
  EXPECT_TRUE(x.isApprox(Vec3(0, 0.01, 0), 1e-12));
  EXPECT_TRUE(v.isApprox(Vec3(0, 0.01, 0), 1e-12));
}

TEST(Trajectory, BadFilesNameFileLineAndField) {
  expect_error("time,finger,x,y\n", ".csv", ":1:", "header");
  expect_error("time,finger,x,y,z\n0,0,0,0,abc\n", ".csv", ":2:", "z 'abc'");
  expect_error("time,finger,x,y,z\n0,3,0,0,0\n", ".csv", ":2:", "finger");
  expect_error("time,finger,x,y,z\n1,0,0,0,0\n0,0,0,0,0\n", ".csv", ":3:", "backwards");
  expect_error("time,finger,x,y,z\n0,0,0,0,0\n", ".csv", "", "no rows for finger 1");
  expect_error("[start]\nfinger0 = [0,0,0]\nfinger1 = [0,0,0]\n[[step]]\nprimitive = \"twirl\"\n",
               ".toml", ":5:", "unknown primitive 'twirl'");
  expect_error("[start]\nfinger0 = [0,0,0]\nfinger1 = [0,0,0]\n[[step]]\nprimitive = \"press\"\ndepth = -1\n",
               ".toml", ":6:", "step[0].depth");
  expect_error("[start]\nfinger0 = [0,0,0]\nfinger1 = [0,0]\n[[step]]\nprimitive = \"hold\"\n",
               ".toml", ":3:", "start.finger1");
  expect_error("[start]\nfinger0 = [0,0,0]\nfinger1 = [0,0,0]\n[[step]]\nprimitive = \"press\"\nheight = 1\n",
               ".toml", ":6:", "not a parameter of 'press'");
  expect_error("x = 1\n", ".yaml", "", ".csv");
}

// A step faster than a hand (kMaxScriptSpeed) is a jump, named by the finger and the times.
TEST(Trajectory, CheckSpeedNamesTheJump) {
  Trajectory tr(2);
  tr.add(0, 0.0, Vec3::Zero());
  tr.add(0, 0.5, Vec3(0.0, 0.0, 0.01));
  tr.add(0, 0.501, Vec3(0.0, 0.0, 0.02));
  tr.add(1, 0.0, Vec3::Zero());
  try {
    tr.check_speed(kMaxScriptSpeed, "s.toml");
    ADD_FAILURE();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("s.toml: finger 0 moves 10 mm in 0.001 s between t = 0.5 and 0.501 s"),
              std::string::npos) << e.what();
  }
}
