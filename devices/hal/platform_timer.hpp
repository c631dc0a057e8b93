// The platform's own timer, measured the way cyclictest (Debian's rt-tests) measures it: a
// thread at the haptic thread's scheduling (SCHED_FIFO 80 when permitted, timer slack 1 ns,
// /dev/cpu_dma_latency held at 0 as cyclictest and the real-time haptic loop hold it) sleeps to absolute 1 kHz deadlines with clock_nanosleep and records how late it woke. No
// spin, no work: what is left is the kernel's wake-up latency, the floor under every
// real-time figure of this project. `hapticloth-bench timer` prints it; `haptic` and `udp` print
// it beside their own figures, measured in the same invocation; the server measures it while
// a real-time session's cloth settles (its preroll) and prints it beside the loop's.
#pragma once

#include <atomic>
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

namespace hapticloth::devices {

/// The haptic thread's SCHED_FIFO priority (the session's), at which the platform is measured.
constexpr int kHapticThreadPriority = 80;

struct TimerFigures {
  long ticks = 0;
  double p50_us = 0.0, p99_us = 0.0, p999_us = 0.0, max_us = 0.0, mean_us = 0.0;
  long over_1ms = 0;       ///< wake-ups more than 1 ms late
  std::string scheduling;  ///< "SCHED_FIFO priority 80" or why not
  std::string idle;        ///< "cpu_dma_latency 0 us" or why not
  nlohmann::json to_json() const;
};

/// Wake-up latency of `ticks` sleeps to absolute deadlines `period` s apart, at SCHED_FIFO
/// `priority` if permitted. A wake-up later than the next deadline skips the deadlines it
/// missed (as cyclictest does), so one late wake-up counts once. With `until`, it stops early
/// once `*until` is true and at least `min_ticks` were taken; with `abort`, as soon as
/// `*abort` is true.
TimerFigures measure_timer(long ticks, double period = 1e-3, int priority = kHapticThreadPriority,
                           const std::atomic<bool>* until = nullptr, long min_ticks = 0,
                           const std::atomic<bool>* abort = nullptr);

}  // namespace hapticloth::devices
