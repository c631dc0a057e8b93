// The monotonic clock in seconds, as the real-time loops sleep on it: absolute deadlines for
// clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, ...). Shared by the session's loops and the
// platform-timer benchmark, which must measure the same clock the same way.
#pragma once

#include <time.h>

namespace hapticloth::devices {

inline double mono_now() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

inline timespec to_timespec(double t) {
  timespec ts;
  ts.tv_sec = static_cast<time_t>(t);
  ts.tv_nsec = static_cast<long>((t - ts.tv_sec) * 1e9);
  if (ts.tv_nsec >= 1000000000L) {
    ++ts.tv_sec;
    ts.tv_nsec -= 1000000000L;
  }
  return ts;
}

}  // namespace hapticloth::devices
