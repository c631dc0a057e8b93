// Keeps the CPUs out of deep idle states while held, through the kernel's PM QoS interface
// (/dev/cpu_dma_latency: write the tolerated wake-up latency, 0 us; the request lasts while the
// file stays open). A thread sleeping to a 1 kHz deadline then wakes sooner, as the CPU need not
// leave a deep idle state first (docs/haptic-loop.md, 'Idle states and the wake-up'). The
// haptic loop holds it for a real-time run; `hapticloth-bench timer` and `udp` hold it too, so
// that they measure what the loop gets.
#pragma once

#include <string>

namespace hapticloth::devices {

class CpuLatencyHold {
 public:
  CpuLatencyHold();  ///< asks for 0 us; never throws (see held() and note())
  ~CpuLatencyHold();
  CpuLatencyHold(const CpuLatencyHold&) = delete;
  CpuLatencyHold& operator=(const CpuLatencyHold&) = delete;

  bool held() const { return fd_ >= 0; }
  /// "cpu_dma_latency 0 us" or why it is not held.
  const std::string& note() const { return note_; }

 private:
  int fd_ = -1;
  std::string note_;
};

}  // namespace hapticloth::devices
