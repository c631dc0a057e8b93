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

// With a tactile display the mock keeps every vibration sample it was sent, per finger, in room
// made at activate (the tick allocates nothing), and the last frame with its pins; past the
// room (TactileRecord::kTactileRecordSeconds) it counts the samples it could not keep.
TEST(MockDevice, RecordsTheTactileOutputWithoutAllocating) {
  DeviceOptions o;
  o.tactile.vibration_rate = 2000;
  o.tactile.pin_rows = 2;
  o.tactile.pin_cols = 2;
  DeviceHandle h(make_device(o));
  ASSERT_EQ(h.configure(), "");
  ASSERT_EQ(h.activate(), "");
  auto& mock = static_cast<MockDevice&>(h.device());
  TactileCommand c;
  const long ticks = static_cast<long>(TactileRecord::kTactileRecordSeconds * 1000) + 10;
  {
    hapticloth::test::AllocationGuard guard;
    for (long k = 0; k < ticks; ++k) {
      c.finger[0].samples = c.finger[1].samples = 2;
      c.finger[0].vibration[0] = static_cast<float>(k);
      c.finger[0].vibration[1] = -static_cast<float>(k);
      c.finger[1].rows = c.finger[1].cols = 2;
      c.finger[1].pins[3] = static_cast<float>(k);
      ASSERT_EQ(h.write_tactile(0.001 * static_cast<double>(k), c), Status::Ok);
    }
    EXPECT_EQ(guard.count(), 0u);
  }
  const TactileRecord& r = mock.tactile_record();
  EXPECT_EQ(r.frames, static_cast<std::uint64_t>(ticks));
  ASSERT_EQ(r.vibration[0].size(), static_cast<size_t>(2000 * TactileRecord::kTactileRecordSeconds));
  EXPECT_EQ(r.vibration[0][2 * 1234], 1234.0f);
  EXPECT_EQ(r.vibration[0][2 * 1234 + 1], -1234.0f);
  EXPECT_EQ(r.dropped_samples, 2u * 2u * 10u);  // two fingers, ten ticks past the room
  EXPECT_EQ(r.last.finger[1].pins[3], static_cast<float>(ticks - 1));
  // Without a display: nothing kept, no room made.
  DeviceHandle plain(make_device(DeviceOptions{}));
  ASSERT_EQ(plain.configure(), "");
  ASSERT_EQ(plain.activate(), "");
  EXPECT_EQ(static_cast<MockDevice&>(plain.device()).tactile_record().vibration[0].capacity(), 0u);
}
