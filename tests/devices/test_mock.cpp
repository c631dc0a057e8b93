// Mock device, trajectories, the device log, the replay device and the driver registry.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include <unistd.h>

#include "hal/handle.hpp"
#include "mock/mock_device.hpp"
#include "mock/trajectory.hpp"
#include "registry.hpp"
#include "replay/replay_device.hpp"
#include "support/alloc_counter.hpp"

using namespace hapticloth::devices;
namespace fs = std::filesystem;

namespace {
std::string tmp_path(const std::string& ext) {
  static int n = 0;
  return (fs::temp_directory_path() /
          ("hc-dev-" + std::to_string(::getpid()) + "-" + std::to_string(n++) + ext))
      .string();
}
std::string write_tmp(const std::string& text, const std::string& ext) {
  const std::string p = tmp_path(ext);
  std::ofstream(p) << text;
  return p;
}
void expect_error(const std::string& text, const std::string& ext, const std::string& where,
                  const std::string& what) {
  const std::string p = write_tmp(text, ext);
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
  const std::string p = write_tmp(R"(
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
  const std::string p = write_tmp("time,finger,x,y,z\n0,0,0,0,0\n1,0,0.01,0,0\n0,1,0,0,0\n2,1,0,0.02,0\n", ".csv");
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

TEST(MockDevice, FollowsItsScriptRecordsForcesAndReadsWithoutAllocating) {
  DeviceOptions o;
  o.record_path = tmp_path(".csv");
  DeviceHandle h(make_device(o));  // the registry's mock, with the built-in demo
  ASSERT_EQ(h.configure(), "");
  ASSERT_EQ(h.activate(), "");
  DeviceState s;
  DeviceCommand c;
  auto& mock = static_cast<MockDevice&>(h.device());
  const double dur = mock.trajectory().duration();
  const int n = static_cast<int>(dur * 1000) + 10;
  {
    hapticloth::test::AllocationGuard guard;
    for (int k = 0; k < n; ++k) {
      const double t = 100.0 + 0.001 * k;  // any loop clock: the script starts at the first read
      ASSERT_EQ(h.read(t, s), Status::Ok);
      Vec3 x, v;
      mock.trajectory().evaluate(0, 0.001 * k, x, v);
      ASSERT_TRUE(s.finger[0].position.isApprox(x, 1e-12) || (x - s.finger[0].position).norm() < 1e-12);
      c.force[0] = Vec3(0, 0, 0.001 * k);
      ASSERT_EQ(h.write(t, c), Status::Ok);
    }
    EXPECT_EQ(guard.count(), 0u);
  }
  EXPECT_EQ(s.sequence, static_cast<std::uint64_t>(n));
  h.deactivate();
  const auto rows = load_device_log(o.record_path);
  ASSERT_EQ(rows.size(), 2u * n);
  EXPECT_NEAR(rows[2 * 100].f.z(), 0.1, 1e-9);
  EXPECT_NEAR(rows[2 * 100].time, 0.1, 1e-9);

  // Replay the log: the same positions come back, and the recorded forces.
  DeviceOptions r;
  r.driver = "replay";
  r.replay_path = o.record_path;
  DeviceHandle hr(make_device(r));
  ASSERT_EQ(hr.configure(), "");
  ASSERT_EQ(hr.activate(), "");
  auto& rep = static_cast<ReplayDevice&>(hr.device());
  for (int k = 0; k < n; k += 97) {
    ASSERT_EQ(hr.read(5.0 + 0.001 * k, s), Status::Ok);
    Vec3 x, v;
    mock.trajectory().evaluate(1, 0.001 * k, x, v);
    EXPECT_LE((s.finger[1].position - x).norm(), 1e-8) << k;
    EXPECT_NEAR(rep.recorded_force(0, 0.001 * k).z(), 0.001 * k, 1e-9);
  }
  fs::remove(o.record_path);
}

TEST(MockDevice, RefusesAScriptOutsideTheWorkspace) {
  DeviceOptions o;
  o.workspace.max = Vec3(0.1, 0.1, 0.02);  // the demo starts at z = 3 cm
  DeviceHandle h(make_device(o));
  const std::string e = h.configure();
  EXPECT_NE(e.find("outside the device workspace"), std::string::npos) << e;
  EXPECT_EQ(h.state(), Lifecycle::Unconfigured);
}

// A script step faster than a hand (kMaxScriptSpeed) is a jump: refused at configure, naming
// the file and line (CSV) or the finger and times (TOML primitives).
TEST(MockDevice, RefusesAScriptThatJumps) {
  DeviceOptions o;
  o.script = write_tmp("time,finger,x,y,z\n0,0,0,0,0.03\n0,1,0.03,0,0.03\n"
                       "1,0,0,0,0.03\n1.001,0,0.014,0,0.03\n1,1,0.03,0,0.03\n",
                       ".csv");
  DeviceHandle h(make_device(o));
  const std::string e = h.configure();
  EXPECT_NE(e.find(o.script + ":5: finger 0 moves 14 mm in 0.001 s"), std::string::npos) << e;
  fs::remove(o.script);
  // At 4.5 m/s, under the limit, the same step is accepted.
  o.script = write_tmp("time,finger,x,y,z\n0,0,0,0,0.03\n0,1,0.03,0,0.03\n"
                       "1,0,0,0,0.03\n1.001,0,0.0045,0,0.03\n1,1,0.03,0,0.03\n",
                       ".csv");
  DeviceHandle ok(make_device(o));
  EXPECT_EQ(ok.configure(), "");
  fs::remove(o.script);
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

TEST(Registry, KnowsItsDriversAndRefusesOthers) {
  const auto n = device_names();
  EXPECT_NE(std::find(n.begin(), n.end(), "mock"), n.end());
  EXPECT_NE(std::find(n.begin(), n.end(), "replay"), n.end());
  DeviceOptions o;
  o.driver = "phantom";
  try {
    make_device(o);
    ADD_FAILURE();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("unknown device 'phantom' (mock"), std::string::npos) << e.what();
  }
  DeviceOptions r;
  r.driver = "replay";  // no log given: a clear configure error
  DeviceHandle h(make_device(r));
  EXPECT_NE(h.configure().find("no device log"), std::string::npos);
  r.replay_path = write_tmp("time,finger,x,y,z\n0,0,0,0,nan\n", ".csv");
  DeviceHandle h2(make_device(r));
  EXPECT_NE(h2.configure().find(":2: z 'nan'"), std::string::npos) << h2.last_error();
  fs::remove(r.replay_path);
}
