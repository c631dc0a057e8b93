// server/haptics/loop/deadlines.hpp: the loop's deadline rules on given times (1 ms period).
#include <gtest/gtest.h>

#include "haptics/loop/deadlines.hpp"

using namespace hapticloth::haptics;

namespace {
constexpr double kP = 1e-3, kStart = 10.0;
}

// A tick on time whose compute fits the period misses nothing.
TEST(Deadlines, ATickOnTimeThatFitsMissesNothing) {
  LoopStats s;
  const long k = tick_after_wake(5, 100, kStart + 5 * kP + 20e-6, kStart, kP, s);
  EXPECT_EQ(k, 5);
  count_deadline(kStart + 5 * kP + 20e-6, kStart + 5 * kP + 30e-6, kStart + 6 * kP, kP, s);
  EXPECT_EQ(s.missed_deadlines, 0u);
  EXPECT_EQ(s.overruns, 0u);
}

// A kernel wake-up 4.3 ms late skips the four ticks due meanwhile (counted missed) and runs the
// one now due; its own compute is short, so it overruns nothing.
TEST(Deadlines, ALateWakeUpSkipsTheTicksDueButOverrunsNone) {
  LoopStats s;
  const double woke = kStart + 5 * kP + 4.3e-3;
  const long k = tick_after_wake(5, 100, woke, kStart, kP, s);
  EXPECT_EQ(k, 9);
  EXPECT_EQ(s.missed_deadlines, 4u);
  count_deadline(woke, woke + 30e-6, kStart + (k + 1) * kP, kP, s);
  EXPECT_EQ(s.missed_deadlines, 4u);
  EXPECT_EQ(s.overruns, 0u);
}

// A tick that computes for 3 ms overruns once and misses its next deadline; the ticks due while
// it ran are then skipped by the next wake-up (3 more missed).
TEST(Deadlines, ATickThatComputesTooLongOverruns) {
  LoopStats s;
  const double woke = kStart + 5 * kP, done = woke + 3e-3;
  count_deadline(woke, done, kStart + 6 * kP, kP, s);
  EXPECT_EQ(s.overruns, 1u);
  EXPECT_EQ(s.missed_deadlines, 1u);
  const long k = tick_after_wake(6, 100, done + 5e-6, kStart, kP, s);
  EXPECT_EQ(k, 8);
  EXPECT_EQ(s.missed_deadlines, 3u);
}

// A late wake-up near the end runs the last tick, not one past the schedule.
TEST(Deadlines, ALateWakeUpAtTheEndRunsTheLastTick) {
  LoopStats s;
  EXPECT_EQ(tick_after_wake(97, 100, kStart + 105 * kP, kStart, kP, s), 99);
  EXPECT_EQ(s.missed_deadlines, 8u);
}
