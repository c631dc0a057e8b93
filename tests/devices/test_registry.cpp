// The driver registry (devices/registry): drivers by name, and a clear error for another name.
#include <gtest/gtest.h>

#include <algorithm>
#include <stdexcept>
#include <string>

#include "registry.hpp"

using namespace hapticloth::devices;

TEST(Registry, KnowsItsDriversAndRefusesOthers) {
  const auto n = device_names();
  EXPECT_TRUE(std::is_sorted(n.begin(), n.end()));
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
  for (const auto& name : n) {
    o.driver = name;
    EXPECT_NE(make_device(o), nullptr) << name;
  }
}
