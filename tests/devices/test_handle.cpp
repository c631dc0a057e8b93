// The device handle (devices/hal/handle.hpp): the driver lifecycle (unconfigured, inactive,
// active, failed) and its errors, and the one check of what a driver says it is
// (devices::validate).
#include <gtest/gtest.h>

#include <memory>

#include "hal/handle.hpp"
#include "support/devices.hpp"

using namespace hapticloth::devices;
using hapticloth::test::two_fingers;


TEST(DeviceInfoCheck, NamesTheFieldThatIsWrong) {
  EXPECT_EQ(validate(two_fingers()), "");
  auto bad = [](auto change) {
    DeviceInfo i = two_fingers();
    change(i);
    return validate(i);
  };
  EXPECT_NE(bad([](DeviceInfo& i) { i.fingers = 1; }).find("fingers 1: a device has 2 to 5"), std::string::npos);
  EXPECT_NE(bad([](DeviceInfo& i) { i.fingers = kMaxFingers + 1; }).find("fingers"), std::string::npos);
  EXPECT_NE(bad([](DeviceInfo& i) { i.max_force = 0.0; }).find("max_force"), std::string::npos);
  EXPECT_NE(bad([](DeviceInfo& i) { i.max_stiffness = NAN; }).find("max_stiffness"), std::string::npos);
  EXPECT_NE(bad([](DeviceInfo& i) { i.nominal_rate = -1.0; }).find("nominal_rate"), std::string::npos);
  EXPECT_NE(bad([](DeviceInfo& i) { i.workspace.max = i.workspace.min; }).find("workspace"), std::string::npos);
}

namespace {
// A scripted driver for the lifecycle tests: fails where told.
struct FakeDriver : Device {
  DeviceInfo inf = two_fingers();
  std::string cfg_err, act_err;
  bool read_error = false;
  int reads = 0, writes = 0, deactivations = 0;
  DeviceCounters cnt;
  const DeviceInfo& info() const override { return inf; }
  std::string configure() override { return cfg_err; }
  std::string activate() override { return act_err; }
  void deactivate() override { ++deactivations; }
  Status read(double, DeviceState&) noexcept override {
    ++reads;
    return read_error ? Status::Error : Status::Ok;
  }
  Status write(double, const DeviceCommand&) noexcept override {
    ++writes;
    return Status::Ok;
  }
  const DeviceCounters& counters() const override { return cnt; }
};
}  // namespace

TEST(DeviceLifecycle, TransitionsAndErrors) {
  auto d = std::make_unique<FakeDriver>();
  FakeDriver* raw = d.get();
  DeviceHandle h(std::move(d));
  DeviceState s;
  DeviceCommand c;
  EXPECT_EQ(h.state(), Lifecycle::Unconfigured);
  EXPECT_EQ(h.read(0, s), Status::Error);  // not active: the driver is not called
  EXPECT_EQ(raw->reads, 0);
  EXPECT_FALSE(h.activate().empty());      // cannot activate before configure
  // A step the driver fails passes its error on and leaves the state; once the driver lets it,
  // the same step moves on.
  auto fails_then_succeeds = [&](std::string& driver_error, const char* error, auto step, Lifecycle before,
                                 Lifecycle after) {
    driver_error = error;
    EXPECT_EQ(step(), error);
    EXPECT_EQ(h.state(), before);
    driver_error.clear();
    EXPECT_EQ(step(), "");
    EXPECT_EQ(h.state(), after);
  };
  fails_then_succeeds(raw->cfg_err, "no such port", [&] { return h.configure(); }, Lifecycle::Unconfigured,
                      Lifecycle::Inactive);
  EXPECT_FALSE(h.configure().empty());     // twice is an error
  fails_then_succeeds(raw->act_err, "rig not answering", [&] { return h.activate(); }, Lifecycle::Inactive,
                      Lifecycle::Active);
  EXPECT_EQ(h.read(0, s), Status::Ok);
  EXPECT_EQ(h.write(0, c), Status::Ok);
  raw->read_error = true;
  EXPECT_EQ(h.read(0.001, s), Status::Error);
  EXPECT_EQ(h.state(), Lifecycle::Failed);
  EXPECT_EQ(h.write(0.001, c), Status::Error);  // failed: no more writes reach the driver
  EXPECT_EQ(raw->writes, 1);
  EXPECT_TRUE(h.failed_since_activation());
  h.deactivate();
  EXPECT_EQ(h.state(), Lifecycle::Inactive);
  EXPECT_TRUE(h.failed_since_activation());  // still known after the session's deactivate: exit 1
  EXPECT_EQ(raw->deactivations, 1);
  raw->read_error = false;
  EXPECT_EQ(h.activate(), "");  // can be reactivated
  EXPECT_FALSE(h.failed_since_activation());
  EXPECT_EQ(h.read(0.002, s), Status::Ok);
  // A driver whose info breaks the HAL contract is refused at configure.
  auto bad = std::make_unique<FakeDriver>();
  bad->inf.fingers = 1;
  DeviceHandle hb(std::move(bad));
  EXPECT_NE(hb.configure().find("fingers"), std::string::npos);
}
