#include "hal/cpu_latency.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstring>

namespace hapticloth::devices {

CpuLatencyHold::CpuLatencyHold() {
  fd_ = ::open("/dev/cpu_dma_latency", O_WRONLY | O_CLOEXEC);
  if (fd_ < 0) {
    note_ = std::string("cpu_dma_latency not held (") + std::strerror(errno) + ")";
    return;
  }
  const std::int32_t us = 0;
  if (::write(fd_, &us, sizeof us) != static_cast<ssize_t>(sizeof us)) {
    note_ = std::string("cpu_dma_latency not held (") + std::strerror(errno) + ")";
    ::close(fd_);
    fd_ = -1;
    return;
  }
  note_ = "cpu_dma_latency 0 us";
}

CpuLatencyHold::~CpuLatencyHold() {
  if (fd_ >= 0) ::close(fd_);
}

}  // namespace hapticloth::devices
