// The remote device: command validation, following injected trajectories, real-time safety.
#include <gtest/gtest.h>

#include "remote/remote_device.hpp"
#include "support/alloc_counter.hpp"

namespace hapticloth::devices {
namespace {

struct Remote : ::testing::Test {
  DeviceOptions opt;
  std::unique_ptr<RemoteDevice> dev;
  DeviceState st;
  void SetUp() override {
    opt.driver = "remote";
    opt.fingers = 2;
    dev = std::make_unique<RemoteDevice>(opt);
    ASSERT_EQ(dev->configure(), "");
    ASSERT_EQ(dev->activate(), "");
    ASSERT_EQ(dev->read(0.0, st), Status::Ok);
  }
  TrajectoryCommand from_here(int f, std::vector<double> t, std::vector<Vec3> p) {
    TrajectoryCommand c;
    c.finger = f;
    c.times = std::move(t);
    c.positions = std::move(p);
    return c;
  }
};

TEST_F(Remote, RestsWhereTheDemoStartsInsideTheWorkspace) {
  for (int f = 0; f < 2; ++f) EXPECT_TRUE(opt.workspace.contains(st.finger[f].position));
  EXPECT_NE(st.finger[0].position, st.finger[1].position);
}

TEST_F(Remote, FollowsTheFirstLegThenThePointsThenHolds) {
  const Vec3 p0 = st.finger[0].position;
  const Vec3 a = p0 + Vec3(0, 0, -0.01), b = a + Vec3(0.02, 0, 0);
  ASSERT_EQ(dev->submit(from_here(0, {0.1, 0.3}, {a, b})), "");
  ASSERT_EQ(dev->read(1.0, st), Status::Ok);  // takes the command at t = 1.0
  EXPECT_EQ(dev->commands_taken(), 1u);
  EXPECT_TRUE(st.finger[0].position.isApprox(p0, 1e-12));
  dev->read(1.05, st);
  EXPECT_TRUE(st.finger[0].position.isApprox(0.5 * (p0 + a), 1e-9));
  EXPECT_TRUE(st.finger[0].velocity.isApprox((a - p0) / 0.1, 1e-9));
  dev->read(1.2, st);
  EXPECT_TRUE(st.finger[0].position.isApprox(0.5 * (a + b), 1e-9));
  dev->read(2.0, st);
  EXPECT_TRUE(st.finger[0].position.isApprox(b, 1e-12));
  EXPECT_EQ(st.finger[0].velocity, Vec3::Zero());
  // The other finger never moved.
  const Vec3 p1 = st.finger[1].position;
  dev->read(2.5, st);
  EXPECT_EQ(st.finger[1].position, p1);
}

TEST_F(Remote, ANewCommandStartsFromWhereTheFingerIs) {
  const Vec3 p0 = st.finger[1].position;
  const Vec3 a = p0 + Vec3(0.05, 0, 0);
  ASSERT_EQ(dev->submit(from_here(1, {0.1}, {a})), "");
  dev->read(0.0, st);
  dev->read(0.05, st);  // halfway
  const Vec3 mid = st.finger[1].position;
  ASSERT_EQ(dev->submit(from_here(1, {0.1}, {p0})), "");  // back, 2.5 cm in 0.1 s
  dev->read(0.05, st);
  EXPECT_TRUE(st.finger[1].position.isApprox(mid, 1e-12));
  dev->read(0.1, st);
  EXPECT_TRUE(st.finger[1].position.isApprox(0.5 * (mid + p0), 1e-9));
}

TEST_F(Remote, RejectsBadCommandsWithTheReason) {
  const Vec3 p0 = st.finger[0].position;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  auto why = [&](TrajectoryCommand c) { return dev->submit(c); };
  EXPECT_NE(why(from_here(0, {0.1}, {Vec3(nan, 0, 0)})).find("not finite"), std::string::npos);
  EXPECT_NE(why(from_here(0, {nan}, {p0})).find("not finite"), std::string::npos);
  EXPECT_NE(why(from_here(0, {0.5}, {Vec3(0, 0, 0.5)})).find("outside the workspace"), std::string::npos);
  EXPECT_NE(why(from_here(0, {0.1, 0.1}, {p0, p0})).find("strictly increasing"), std::string::npos);
  EXPECT_NE(why(from_here(0, {-0.1}, {p0})).find("negative time"), std::string::npos);
  EXPECT_NE(why(from_here(0, {0.1, 0.11}, {p0, p0 + Vec3(0.02, 0, 0)})).find("above the limit"),
            std::string::npos);  // 2 m/s
  EXPECT_NE(why(from_here(0, {0.0}, {p0 + Vec3(0.01, 0, 0)})).find("too far"), std::string::npos);
  EXPECT_NE(why(from_here(5, {0.1}, {p0})).find("out of range"), std::string::npos);
  EXPECT_NE(why(from_here(0, {}, {})).find("no points"), std::string::npos);
  auto c = from_here(0, {0.1}, {p0});
  c.positions.clear();
  EXPECT_NE(why(c).find("differ"), std::string::npos);
  // A raised limit lets the fast stroke through; nothing rejected reached the device.
  EXPECT_EQ(dev->commands_taken(), 0u);
  dev->set_max_speed(3.0);
  EXPECT_EQ(why(from_here(0, {0.1, 0.11}, {p0, p0 + Vec3(0.02, 0, 0)})), "");
  // A jump of under a millimetre at t = 0 is allowed (one tick of motion).
  EXPECT_EQ(why(from_here(1, {0.0}, {st.finger[1].position + Vec3(0.0005, 0, 0)})), "");
}

// Issue 36 item 15: the replay test's two fingers were sent back to back but, on a loaded
// machine, taken tens of ticks apart (each at the tick it arrived), so the recorded pinch was
// replayed out of step. Commands of one source and utime are one batch: the second finger's
// starts at the first's time 0, and its first leg takes what is left of that.
TEST_F(Remote, ABatchStartsTogetherHoweverFarApartItArrives) {
  const Vec3 p0 = st.finger[0].position, p1 = st.finger[1].position;
  const Vec3 a0 = p0 + Vec3(0.0, 0.0, -0.01), a1 = p1 + Vec3(0.0, 0.0, -0.01);
  const Vec3 b0 = a0 + Vec3(0.02, 0, 0), b1 = a1 + Vec3(0.02, 0, 0);
  TrajectoryCommand c0 = from_here(0, {0.1, 0.3}, {a0, b0}), c1 = from_here(1, {0.1, 0.3}, {a1, b1});
  c0.source = c1.source = "replay";
  c0.utime = c1.utime = 1234567;
  ASSERT_EQ(dev->submit(c0), "");
  ASSERT_EQ(dev->read(1.0, st), Status::Ok);   // finger 0 taken at t = 1.0
  ASSERT_EQ(dev->submit(c1), "");
  ASSERT_EQ(dev->read(1.04, st), Status::Ok);  // finger 1 taken 40 ticks later
  EXPECT_TRUE(st.finger[1].position.isApprox(p1, 1e-12));  // no jump where it is taken
  dev->read(1.07, st);  // both halfway through the remaining leg: finger 1 faster to catch up
  EXPECT_TRUE(st.finger[0].position.isApprox(p0 + 0.7 * (a0 - p0), 1e-9));
  EXPECT_TRUE(st.finger[1].position.isApprox(p1 + 0.5 * (a1 - p1), 1e-9));
  for (double t : {1.1, 1.2, 1.35}) {  // from the first point on, in step
    dev->read(t, st);
    EXPECT_TRUE((st.finger[1].position - st.finger[0].position).isApprox(p1 - p0, 1e-9)) << t;
  }
  // Another utime, or another source, is not the batch: it starts when taken.
  TrajectoryCommand d = from_here(1, {0.1}, {b1 + Vec3(0, 0.01, 0)});
  d.source = "replay";
  d.utime = 7654321;
  ASSERT_EQ(dev->submit(d), "");
  dev->read(2.0, st);
  dev->read(2.05, st);
  EXPECT_TRUE(st.finger[1].position.isApprox(b1 + Vec3(0, 0.005, 0), 1e-9));
}

// A batch member taken too late to reach its first point in time at the speed limit starts
// when it is taken (never faster than the limit).
TEST_F(Remote, ABatchMemberTooLateStartsWhenTaken) {
  dev->set_max_speed(0.1);
  const Vec3 p0 = st.finger[0].position, p1 = st.finger[1].position;
  TrajectoryCommand c0 = from_here(0, {0.1}, {p0 + Vec3(0, 0, -0.005)});
  TrajectoryCommand c1 = from_here(1, {0.1}, {p1 + Vec3(0, 0, -0.008)});
  c0.source = c1.source = "s";
  c0.utime = c1.utime = 42;
  ASSERT_EQ(dev->submit(c0), "");
  dev->read(1.0, st);
  ASSERT_EQ(dev->submit(c1), "");
  dev->read(1.05, st);  // 0.05 s left for 8 mm: 0.16 m/s, over the limit
  dev->read(1.1, st);
  EXPECT_TRUE(st.finger[1].position.isApprox(p1 + Vec3(0, 0, -0.004), 1e-9));
}

TEST_F(Remote, ReadAndWriteDoNotAllocate) {
  const Vec3 p0 = st.finger[0].position;
  ASSERT_EQ(dev->submit(from_here(0, {0.1, 0.2}, {p0 + Vec3(0, 0, -0.01), p0})), "");
  DeviceCommand cmd;
  test::AllocationGuard guard;
  for (int k = 0; k < 1000; ++k) {
    dev->read(k * 1e-3, st);
    dev->write(k * 1e-3, cmd);
  }
  EXPECT_EQ(guard.count(), 0u);
  EXPECT_EQ(dev->counters().reads, 1001u);
}

}  // namespace
}  // namespace hapticloth::devices
