// CpuLatencyHold (devices/hal/cpu_latency.cpp): while held, the kernel's PM QoS request for CPU
// wake-up latency is 0 us (reading /dev/cpu_dma_latency gives the request in force); released,
// it goes back to what it was. Where the file cannot be opened (no root, no such device), the
// hold says why instead of failing.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <unistd.h>

#include <cstdint>
#include <optional>

#include "hal/cpu_latency.hpp"

using hapticloth::devices::CpuLatencyHold;

namespace {

// The PM QoS CPU latency in force, us (nullopt: not readable here).
std::optional<std::int32_t> latency_in_force() {
  const int fd = ::open("/dev/cpu_dma_latency", O_RDONLY | O_CLOEXEC);
  if (fd < 0) return std::nullopt;
  std::int32_t us = -1;
  const bool ok = ::read(fd, &us, sizeof us) == static_cast<ssize_t>(sizeof us);
  ::close(fd);
  return ok ? std::optional<std::int32_t>(us) : std::nullopt;
}

}  // namespace

TEST(CpuLatencyHold, HoldsZeroWhileAliveAndReleasesAfter) {
  const std::optional<std::int32_t> before = latency_in_force();
  {
    const CpuLatencyHold hold;
    if (!hold.held()) {
      EXPECT_NE(hold.note().find("not held ("), std::string::npos) << hold.note();  // says why
      GTEST_SKIP() << hold.note();
    }
    EXPECT_EQ(hold.note(), "cpu_dma_latency 0 us");
    ASSERT_TRUE(latency_in_force().has_value());
    EXPECT_EQ(*latency_in_force(), 0);
  }
  EXPECT_EQ(latency_in_force(), before);  // the request ended with the hold
}
