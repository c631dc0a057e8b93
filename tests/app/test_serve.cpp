// Running a scene with a device (server/app/serve): a device that fails during the session
// ends it with exit status 1 and says so; the same session with a healthy device ends with 0.
// A real-time session reports the platform's timer beside its own period error.
#include <gtest/gtest.h>

#include <limits>
#include <memory>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

#include "app/serve.hpp"
#include "cloth/mesh.hpp"
#include "mock/mock_device.hpp"
#include "support/fixtures.hpp"

namespace {

using namespace hapticloth;
using devices::DeviceState;
using devices::Status;

// The mock device whose reads fail (Status::Error) from `fail_after` seconds of loop time on,
// as a driver does that loses its device in the middle of a session.
class FailingDevice final : public devices::Device {
 public:
  FailingDevice(const devices::DeviceOptions& opt, double fail_after)
      : mock_(opt), fail_after_(fail_after) {}
  const devices::DeviceInfo& info() const override { return mock_.info(); }
  std::string configure() override { return mock_.configure(); }
  std::string activate() override {
    t0_ = -1.0;
    return mock_.activate();
  }
  void deactivate() override { mock_.deactivate(); }
  Status read(double now, DeviceState& state) noexcept override {
    if (t0_ < 0.0) t0_ = now;
    if (now - t0_ >= fail_after_) return Status::Error;
    return mock_.read(now, state);
  }
  Status write(double now, const devices::DeviceCommand& cmd) noexcept override {
    return mock_.write(now, cmd);
  }
  const devices::DeviceCounters& counters() const override { return mock_.counters(); }

 private:
  devices::MockDevice mock_;
  double fail_after_;
  double t0_ = -1.0;
};

// A 0.3 m square of denim hanging from its top edge, with the mock device's default options.
app::Scene small_scene() {
  app::Scene s;
  s.name = "serve-test";
  cloth::GridSpec g;
  g.width = g.height = 0.3;
  g.nx = g.ny = 8;
  g.origin = {-0.15, -0.15, 0.0};
  s.mesh = cloth::make_grid(g);
  s.material = test::denim();
  s.pins = cloth::grid_edge(s.mesh, "top");
  s.duration = 0.3;
  s.has_device = true;
  return s;
}

struct Served {
  int status;
  std::string out, err;
};

// serve() without transports, with a FailingDevice, on a stepped clock (or in real time).
Served serve_with(double fail_after, bool realtime = false, bool json = false) {
  app::ServeOptions opt;
  opt.realtime = realtime;
  opt.json = json;
  opt.transport.zenoh = false;
  opt.transport.lcm_log.clear();
  opt.make_device = [fail_after](const devices::DeviceOptions& o) {
    return std::make_unique<FailingDevice>(o, fail_after);
  };
  std::ostringstream out;
  testing::internal::CaptureStderr();
  const int status = app::serve(small_scene(), opt, out);
  return {status, out.str(), testing::internal::GetCapturedStderr()};
}

TEST(Serve, ADeviceThatFailsDuringTheSessionEndsItWithExit1) {
  const Served s = serve_with(0.1);
  EXPECT_EQ(s.status, 1) << s.out << s.err;
  EXPECT_NE(s.err.find("hapticloth-server: device mock failed during the session"), std::string::npos)
      << s.err;
  EXPECT_NE(s.out.find("haptic ticks"), std::string::npos) << "the summary is still printed:\n" << s.out;
}

TEST(Serve, AHealthyDeviceEndsTheSessionWithExit0) {
  const Served s = serve_with(std::numeric_limits<double>::infinity());
  EXPECT_EQ(s.status, 0) << s.out << s.err;
  EXPECT_EQ(s.err.find("failed"), std::string::npos) << s.err;
}

// The platform timer is measured while the cloth settles, for at least 1000 ticks (1 s at
// 1 kHz, longer than this scene's preroll), and printed after the loop's own figures.
TEST(Serve, ARealTimeSessionReportsThePlatformTimerBesideItsOwn) {
  const Served text = serve_with(std::numeric_limits<double>::infinity(), true);
  ASSERT_EQ(text.status, 0) << text.out << text.err;
  const size_t period = text.out.find("period error"), platform = text.out.find("platform timer   p50 ");
  ASSERT_NE(platform, std::string::npos) << text.out;
  EXPECT_LT(period, platform) << text.out;
  EXPECT_NE(text.out.find("during the preroll"), std::string::npos) << text.out;

  const Served js = serve_with(std::numeric_limits<double>::infinity(), true, true);
  ASSERT_EQ(js.status, 0) << js.err;
  const auto j = nlohmann::json::parse(js.out);
  ASSERT_TRUE(j.contains("platform_timer")) << js.out;
  const auto& t = j["platform_timer"];
  EXPECT_GE(t["ticks"].get<long>(), 1000);
  EXPECT_LT(t["ticks"].get<long>(), 60000) << "stopped once the preroll ended";
  EXPECT_GE(t["p99_us"].get<double>(), t["p50_us"].get<double>());
  EXPECT_GE(t["max_us"].get<double>(), t["p99_us"].get<double>());
  EXPECT_GT(t["p50_us"].get<double>(), 0.0) << "a sleeping thread never wakes before its deadline";
  EXPECT_TRUE(j.contains("period_error_p99_excess_us")) << js.out;
}

TEST(Serve, ASteppedSessionHasNoPlatformTimer) {
  const Served js = serve_with(std::numeric_limits<double>::infinity(), false, true);
  ASSERT_EQ(js.status, 0) << js.err;
  EXPECT_FALSE(nlohmann::json::parse(js.out).contains("platform_timer")) << js.out;
}

}  // namespace
