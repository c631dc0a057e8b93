// The replay device (devices/replay/replay_device): plays a device log back on the loop clock,
// keeps the recorded forces, and refuses a missing or bad log at configure.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "hal/handle.hpp"
#include "log/device_log.hpp"
#include "mock/trajectory.hpp"
#include "registry.hpp"
#include "replay/replay_device.hpp"
#include "support/temp_files.hpp"

using namespace hapticloth::devices;
using hapticloth::test::temp_path;
using hapticloth::test::write_temp;
namespace fs = std::filesystem;

TEST(ReplayDevice, PlaysBackTheLoggedPositionsAndKeepsTheForces) {
  // The log of the demo trajectory at 1 kHz, from log time 0.5 s, with a force growing in time.
  const Trajectory demo = demo_trajectory(2);
  const int n = static_cast<int>(demo.duration() * 1000) + 10;
  const std::string path = temp_path(".csv");
  {
    DeviceLogWriter log;
    ASSERT_EQ(log.open(path), "");
    DeviceState s;
    DeviceCommand c;
    for (int k = 0; k < n; ++k) {
      demo.sample(2, 0.001 * k, 0.0, s);
      c.force[0] = Vec3(0, 0, 0.001 * k);
      log.record(0.5 + 0.001 * k, 2, s, c);
    }
    ASSERT_EQ(log.close(), "");
    ASSERT_EQ(log.dropped(), 0u);
  }
  DeviceOptions r;
  r.driver = "replay";
  r.replay_path = path;
  DeviceHandle h(make_device(r));
  ASSERT_EQ(h.configure(), "");
  ASSERT_EQ(h.activate(), "");
  auto& rep = static_cast<ReplayDevice&>(h.device());
  DeviceState s;
  for (int k = 0; k < n; k += 97) {
    // Any loop clock: the log's first sample plays at the first read.
    ASSERT_EQ(h.read(5.0 + 0.001 * k, s), Status::Ok);
    Vec3 x, v;
    demo.evaluate(1, 0.001 * k, x, v);
    EXPECT_LE((s.finger[1].position - x).norm(), 1e-8) << k;
    EXPECT_NEAR(rep.recorded_force(0, 0.5 + 0.001 * k).z(), 0.001 * k, 1e-9);
  }
  fs::remove(path);
}

TEST(ReplayDevice, RefusesAMissingOrBadLog) {
  DeviceOptions r;
  r.driver = "replay";  // no log given: a clear configure error
  DeviceHandle h(make_device(r));
  EXPECT_NE(h.configure().find("no device log"), std::string::npos);
  r.replay_path = write_temp("time,finger,x,y,z\n0,0,0,0,nan\n", ".csv");
  DeviceHandle h2(make_device(r));
  EXPECT_NE(h2.configure().find(":2: z 'nan'"), std::string::npos) << h2.last_error();
  fs::remove(r.replay_path);
}
