// The mock device (devices/mock/mock_device): follows its script, records what it was sent,
// reads without allocating, and refuses a script outside the workspace or one that jumps.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "hal/handle.hpp"
#include "mock/mock_device.hpp"
#include "mock/trajectory.hpp"
#include "registry.hpp"
#include "support/alloc_counter.hpp"
#include "support/temp_files.hpp"

using namespace hapticloth::devices;
using hapticloth::test::temp_path;
using hapticloth::test::write_temp;
namespace fs = std::filesystem;

TEST(MockDevice, FollowsItsScriptRecordsForcesAndReadsWithoutAllocating) {
  DeviceOptions o;
  o.record_path = temp_path(".csv");
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
  Vec3 x, v;
  mock.trajectory().evaluate(1, 0.1, x, v);
  EXPECT_LE((rows[2 * 100 + 1].x - x).norm(), 1e-8);
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
// the file and line (CSV; test_trajectory has the TOML primitives' message).
TEST(MockDevice, RefusesAScriptThatJumps) {
  DeviceOptions o;
  o.script = write_temp("time,finger,x,y,z\n0,0,0,0,0.03\n0,1,0.03,0,0.03\n"
                        "1,0,0,0,0.03\n1.001,0,0.014,0,0.03\n1,1,0.03,0,0.03\n",
                        ".csv");
  DeviceHandle h(make_device(o));
  const std::string e = h.configure();
  EXPECT_NE(e.find(o.script + ":5: finger 0 moves 14 mm in 0.001 s"), std::string::npos) << e;
  fs::remove(o.script);
  // At 4.5 m/s, under the limit, the same step is accepted.
  o.script = write_temp("time,finger,x,y,z\n0,0,0,0,0.03\n0,1,0.03,0,0.03\n"
                        "1,0,0,0,0.03\n1.001,0,0.0045,0,0.03\n1,1,0.03,0,0.03\n",
                        ".csv");
  DeviceHandle ok(make_device(o));
  EXPECT_EQ(ok.configure(), "");
  fs::remove(o.script);
}
