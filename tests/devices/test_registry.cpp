// The driver registry (devices/registry): drivers by name, and a clear error for another name.
#include <gtest/gtest.h>

#include <algorithm>
#include <stdexcept>
#include <string>

#include "registry.hpp"

using namespace hapticloth::devices;

namespace {
// Options every driver can be made from: a composite's two one-finger UDP parts included.
DeviceOptions any_driver() {
  DeviceOptions o;
  o.udp_bind = "127.0.0.1:0";
  DeviceOptions part;
  part.driver = "udp";
  part.udp_bind = "127.0.0.1:0";
  o.parts = {part, part};
  return o;
}
}  // namespace

TEST(Registry, KnowsItsDriversAndRefusesOthers) {
  const auto n = device_names();
  EXPECT_TRUE(std::is_sorted(n.begin(), n.end()));
  EXPECT_NE(std::find(n.begin(), n.end(), "mock"), n.end());
  EXPECT_NE(std::find(n.begin(), n.end(), "replay"), n.end());
  DeviceOptions o = any_driver();
  o.driver = "phantom";
  try {
    make_device(o);
    ADD_FAILURE();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("unknown device 'phantom' (composite, mock"), std::string::npos) << e.what();
  }
  for (const auto& name : n) {
    o.driver = name;
    EXPECT_NE(make_device(o), nullptr) << name;
  }
}

// The registry's word on which drivers pace the loop (what scene files are checked against)
// is each driver's own.
TEST(Registry, KnowsWhichDriversPaceTheLoop) {
  DeviceOptions o = any_driver();
  bool any = false;
  for (const auto& name : device_names()) {
    o.driver = name;
    const bool paces = make_device(o)->paces_loop();
    EXPECT_EQ(driver_paces_loop(name), paces) << name;
    any = any || paces;
  }
  EXPECT_TRUE(any) << "no driver paces the loop (udp should)";
  EXPECT_FALSE(driver_paces_loop("phantom"));
}
