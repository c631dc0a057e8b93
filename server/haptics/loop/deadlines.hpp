// The real-time loop's deadline rules, apart from its clock so that a test can give them any
// times: which tick a late wake-up runs, and what a tick that ends late counts as.
#pragma once

#include <algorithm>

#include "haptics/loop/stats.hpp"

namespace hapticloth::haptics {

/// Tick `k` of a schedule with deadlines t_start + k period, `ticks` in all, woke at `woke`:
/// returns the tick to run. A wake-up more than a period late (the kernel now and then wakes a
/// thread milliseconds late) skips the ticks due meanwhile, counted as missed, rather than
/// running them in a burst.
inline long tick_after_wake(long k, long ticks, double woke, double t_start, double period, LoopStats& s) {
  const long due = static_cast<long>((woke - t_start) / period);
  if (due <= k) return k;
  s.missed_deadlines += static_cast<std::uint64_t>(due - k);
  return std::min(due, ticks - 1);
}

/// A tick begun at `woke` and done at `done` missed `next` (the next deadline) if it ended
/// after it, whatever made it late; it overran if its own compute (the loop and its observers)
/// took longer than the period, which a late start alone never makes it do.
inline void count_deadline(double woke, double done, double next, double period, LoopStats& s) {
  if (done > next) ++s.missed_deadlines;
  if (done - woke > period) ++s.overruns;
}

}  // namespace hapticloth::haptics
