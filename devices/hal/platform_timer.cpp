#include "hal/platform_timer.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/prctl.h>
#include <time.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <thread>
#include <vector>

#include "hal/cpu_latency.hpp"
#include "hal/mono_clock.hpp"

namespace hapticloth::devices {

namespace {
double percentile(const std::vector<double>& sorted, double q) {
  if (sorted.empty()) return 0.0;
  const size_t i = std::min(sorted.size() - 1, static_cast<size_t>(std::ceil(q * sorted.size())) - 1);
  return sorted[i];
}
}  // namespace

nlohmann::json TimerFigures::to_json() const {
  return {{"ticks", ticks},   {"p50_us", p50_us}, {"p99_us", p99_us},     {"p999_us", p999_us},
          {"max_us", max_us}, {"mean_us", mean_us}, {"over_1ms", over_1ms}, {"scheduling", scheduling},
          {"idle_states", idle}};
}

TimerFigures measure_timer(long ticks, double period, int priority, const std::atomic<bool>* until,
                           long min_ticks, const std::atomic<bool>* abort) {
  TimerFigures out;
  std::vector<double> late;
  late.reserve(static_cast<size_t>(std::max(0L, ticks)));
  const CpuLatencyHold idle;  // as the haptic loop holds it
  out.idle = idle.note();
  std::thread t([&] {
    prctl(PR_SET_TIMERSLACK, 1UL, 0, 0, 0);
    sched_param sp{};
    sp.sched_priority = priority;
    const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
    out.scheduling = rc == 0 ? "SCHED_FIFO priority " + std::to_string(priority)
                             : std::string("SCHED_FIFO refused (") + std::strerror(rc) + "): normal scheduling";
    double deadline = mono_now() + period;
    for (long k = 0; k < ticks; ++k) {
      if (until && k >= min_ticks && until->load(std::memory_order_relaxed)) break;
      if (abort && abort->load(std::memory_order_relaxed)) break;
      const timespec ts = to_timespec(deadline);
      clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
      const double woke = mono_now();
      late.push_back((woke - deadline) * 1e6);
      deadline += period;
      while (deadline <= woke) deadline += period;  // the deadlines missed meanwhile: skipped
    }
  });
  t.join();
  out.ticks = static_cast<long>(late.size());
  if (late.empty()) return out;
  double sum = 0.0;
  for (double l : late) {
    sum += l;
    out.over_1ms += l > 1000.0;
  }
  out.mean_us = sum / late.size();
  std::sort(late.begin(), late.end());
  out.p50_us = percentile(late, 0.50);
  out.p99_us = percentile(late, 0.99);
  out.p999_us = percentile(late, 0.999);
  out.max_us = late.back();
  return out;
}

}  // namespace hapticloth::devices
