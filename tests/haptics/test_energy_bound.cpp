// The multirate path's energy bound (server/haptics/modes/energy_bound.cpp): a model that lags the
// hand gives it energy over closed cycles; bounded, it returns no more than it was given, over
// every stretch of a touch, and keeps the force across the motion. End to end, the drum
// pressed and released over closed cycles gives the user no energy with direct coupling nor on
// the multirate path at 10 and 20 ms global steps.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "haptics/modes/energy_bound.hpp"
#include "support/touch_scenes.hpp"

using namespace hapticloth;
using haptics::EnergyBound;
using haptics::kMaxFingers;
using haptics::Vec3;

namespace {
constexpr double kT = 1e-3;  // s, the haptic tick

// Vectors per finger, zero (an Eigen vector's default constructor leaves it uninitialised).
std::array<Vec3, kMaxFingers> zeros() {
  std::array<Vec3, kMaxFingers> a;
  a.fill(Vec3::Zero());
  return a;
}

constexpr double kK = 200.0, kA = 0.004, kW = 2 * M_PI * 2.0;  // N/m, m, rad/s

// What the bound may be off by: it limits the coming tick's work with the velocity at its
// start, so a force F misjudges it by at most |F| |a| T^2 (a the acceleration), here
// k A x A w^2 / 2 x T^2 = 0.25 uJ a tick.
constexpr double kOneTickError = kK * kA * (0.5 * kA * kW * kW) * kT * kT;

// One finger pressing a spring k (and a damper b) along z whose force lags the finger by `lag` s
// (a model that follows the cloth one step late): x = A (1 - cos w t) / 2 below the surface,
// at 2 Hz for `cycles`. Returns the work the sent forces did on the hand over each cycle, J
// (> 0: energy given), and the largest running sum of it over the whole touch.
struct LagRun {
  std::vector<double> per_cycle;
  double worst_running = 0.0;  // the most energy the hand had got back, net, at any tick
  double peak_force = 0.0;
  std::uint64_t limited = 0;
};
LagRun lagging_spring(bool bounded, double lag, double b = 0.0, int cycles = 3) {
  const double k = kK, A = kA, f = 2.0, w = kW;
  const int per_cycle = static_cast<int>(std::lround(1.0 / (f * kT)));
  EnergyBound bound(kT);
  std::array<Vec3, kMaxFingers> x = zeros(), sent = zeros(), force = zeros(), v = zeros();
  std::array<bool, kMaxFingers> present{}, touching{};
  present[0] = true;
  LagRun r;
  r.per_cycle.assign(cycles, 0.0);
  double running = 0.0;
  Vec3 last = Vec3::Zero();
  for (int n = 0; n <= cycles * per_cycle; ++n) {
    const double t = n * kT;
    x[0] = Vec3(0, 0, -0.5 * A * (1.0 - std::cos(w * t)));
    v[0] = Vec3(0, 0, -0.5 * A * w * std::sin(w * t));
    const double work = sent[0].dot(x[0] - last);  // what the held force did on the hand
    if (n > 0) r.per_cycle[std::min(cycles - 1, (n - 1) / per_cycle)] += work;
    running += work;
    r.worst_running = std::max(r.worst_running, running);
    last = x[0];
    if (bounded) bound.account(x, sent, present, 1);
    const double lagged = 0.5 * A * (1.0 - std::cos(w * std::max(0.0, t - lag)));
    force[0] = Vec3(0, 0, k * lagged) - b * v[0];
    touching[0] = true;
    if (bounded) bound.limit(force, v, touching, 1);
    sent[0] = force[0];
    r.peak_force = std::max(r.peak_force, force[0].z());
  }
  r.limited = bound.stats().limited_ticks;
  return r;
}
// Prints a run of closed cycles and expects no cycle to give the user energy.
void expect_no_energy_given(const std::string& label, const test::CycleResult& r) {
  std::printf("%s: peak %.3f N, work on the user per cycle", label.c_str(), r.peak_force);
  for (double w : r.work_on_user) std::printf(" %+.3f", w * 1e6);
  std::printf(" uJ; bound on %llu ticks, %.2f uJ withheld\n",
              static_cast<unsigned long long>(r.report.energy_bound_ticks), r.report.energy_withheld * 1e6);
  for (double w : r.work_on_user) EXPECT_LE(w, 1e-8) << label;
}

std::string label(const char* what, double dt, double hz) {
  char b[96];
  std::snprintf(b, sizeof b, "%s, global step %2.0f ms, %.0f Hz", what, dt * 1e3, hz);
  return b;
}
}  // namespace

// Unbounded, a spring 20 ms late gives the hand energy every cycle (the multirate path's fault
// in small); bounded, the running sum of what it gave never exceeds what it took.
TEST(EnergyBound, ALaggingModelGivesNoEnergyBack) {
  const LagRun free = lagging_spring(false, 0.02), held = lagging_spring(true, 0.02);
  for (int c = 0; c < 3; ++c) {
    std::printf("cycle %d: work on the hand %+.2f uJ unbounded, %+.4f uJ bounded\n", c,
                free.per_cycle[c] * 1e6, held.per_cycle[c] * 1e6);
    EXPECT_GT(free.per_cycle[c], 1e-6);  // the lag's energy: k A^2 w lag pi / 4 ~ 40 uJ
    EXPECT_LE(held.per_cycle[c], kOneTickError);
  }
  EXPECT_LE(held.worst_running, kOneTickError);
  EXPECT_NEAR(held.peak_force, free.peak_force, 1e-9);  // the press is not touched
}

// A spring held over each tick is itself late by half a tick and gives (pi / 4) k A^2 w T / 2 =
// 16 uJ a cycle; with a damper past Colgate's b > k T / 2 it is passive, and the bound leaves
// it alone.
TEST(EnergyBound, LeavesAPassiveModelAlone) {
  const LagRun spring = lagging_spring(false, 0.0);
  EXPECT_NEAR(spring.per_cycle[1], M_PI / 4 * kK * kA * kA * kW * kT / 2, 1e-6);
  const double b = kK * kT;  // twice Colgate's bound
  const LagRun free = lagging_spring(false, 0.0, b), held = lagging_spring(true, 0.0, b);
  for (int c = 0; c < 3; ++c) {
    EXPECT_LT(free.per_cycle[c], 0.0);
    EXPECT_EQ(held.per_cycle[c], free.per_cycle[c]);
  }
  EXPECT_EQ(held.limited, 0u);
}

// Only the part of a force along the motion does work: a force across it (a stroke's normal
// force while the finger slides) is kept whole.
TEST(EnergyBound, KeepsTheForceAcrossTheMotion) {
  EnergyBound bound(kT);
  std::array<Vec3, kMaxFingers> x = zeros(), sent = zeros(), force = zeros(), v = zeros();
  std::array<bool, kMaxFingers> present{}, touching{};
  present[0] = touching[0] = true;
  bound.account(x, sent, present, 1);
  force[0] = Vec3(0.3, 0.0, 1.0);  // pushes the finger along +x, which it moves along
  v[0] = Vec3(0.05, 0.0, 0.0);
  bound.limit(force, v, touching, 1);  // nothing put in yet: the push along x is withheld
  EXPECT_NEAR(force[0].x(), 0.0, 1e-15);
  EXPECT_EQ(force[0].z(), 1.0);
  EXPECT_EQ(bound.stats().limited_ticks, 1u);
}

// The reserve is the hand's net work since the touch began: spent by one finger, taken by the
// other (a pinch shares one cloth), and emptied when no finger touches.
TEST(EnergyBound, OneReserveForAllFingersEmptiedBetweenTouches) {
  EnergyBound bound(kT);
  std::array<Vec3, kMaxFingers> x = zeros(), sent = zeros(), force = zeros(), v = zeros();
  std::array<bool, kMaxFingers> present{}, touching{};
  present[0] = present[1] = touching[0] = touching[1] = true;
  bound.account(x, sent, present, 2);
  bound.limit(force, v, touching, 2);
  sent[0] = Vec3(0, 0, 1.0);  // finger 0 pushes down 1 mm against 1 N: 1 mJ in
  x[0] = Vec3(0, 0, -1e-3);
  bound.account(x, sent, present, 2);
  EXPECT_NEAR(bound.reserve(), 1e-3, 1e-15);
  force[1] = Vec3(0, 0, -2.0);  // finger 1 would get 2 N x 1 m/s x 1 ms = 2 mJ
  v[1] = Vec3(0, 0, -1.0);
  bound.limit(force, v, touching, 2);
  EXPECT_NEAR(force[1].z(), -1.0, 1e-12);  // half of it: the 1 mJ finger 0 put in
  touching = {};
  bound.limit(force, v, touching, 2);
  bound.account(x, sent, present, 2);
  EXPECT_EQ(bound.reserve(), 0.0);
}

// End to end: the drum of membrane theory (8 mm fingertip, 2 mm centre edges) pressed from 1 mm
// above touch to 3 mm below and back, 3 cycles at 1, 2 and 5 Hz. Direct coupling absorbs what
// its damping and the implicit step dissipate; the multirate path (the response model at 10 and
// 20 ms) gave 3-35 uJ a cycle before the bound, and gives none now. Its press is not changed:
// the peak force stays within 3% of direct coupling's.
TEST(EnergyBound, DrumCyclesGiveTheUserNoEnergy) {
  double direct_peak = 0.0;
  for (double dt : {1e-3, 1e-2, 2e-2})
    for (double hz : {1.0, 2.0, 5.0}) {
      test::CycleSpec c;
      c.drum.centre_edge = 2e-3;
      c.drum.global_dt = dt;
      c.frequency = hz;
      c.cycles = 3;
      const test::CycleResult r = test::cycle_drum(c);
      expect_no_energy_given(label("drum", dt, hz), r);
      if (dt == 1e-3 && hz == 1.0) direct_peak = r.peak_force;
      if (hz == 1.0) {
        EXPECT_NEAR(r.peak_force / direct_peak, 1.0, 0.03) << dt;
      }
    }
}

// The same cycles on a uniform 12 mm mesh with local refinement, whose compliance in series with
// the coupling changes from step to step (a spring whose stiffness changes while stretched is
// not passive): at 20 ms global steps the bound keeps every cycle from giving the user energy;
// with direct coupling (no bound) the compliance's bounded rate (FingertipContact::
// approach_refined_compliance) and the implicit step's damping keep every cycle dissipative.
TEST(EnergyBound, RefinedDrumCyclesGiveTheUserNoEnergy) {
  for (double dt : {1e-3, 2e-2})
  for (double hz : {1.0, 5.0}) {
    test::CycleSpec c;
    c.drum.centre_edge = c.drum.rim_edge = 12e-3;
    c.drum.refine = haptics::Refine::On;
    c.drum.global_dt = dt;
    c.frequency = hz;
    c.cycles = 3;
    expect_no_energy_given(label("refined 12 mm drum", dt, hz), test::cycle_drum(c));
  }
}

// The hanging square of the main job at rest, pressed at its middle horizontally from 1 mm before
// touch to 30 mm past it and back (a hanging cloth gives way), 3 cycles at 1 and 5 Hz, with the
// scene's default refinement (its 23 mm elements refined under the fingertip): no cycle gives the
// user energy, with direct coupling nor
// on the multirate path at 10 and 20 ms.
TEST(EnergyBound, HangingSquareCyclesGiveTheUserNoEnergy) {
  for (double dt : {1e-3, 1e-2, 2e-2})
    for (double hz : {1.0, 5.0}) {
      test::CycleSpec c;
      c.drum.refine = haptics::Refine::Auto;
      c.drum.global_dt = dt;
      c.frequency = hz;
      c.cycles = 3;
      c.depth = 30e-3;
      const test::CycleResult r = test::cycle_hanging_square(c);
      expect_no_energy_given(label("hanging square", dt, hz), r);
      EXPECT_GT(r.peak_force, 0.005) << dt << " s, " << hz << " Hz";  // it was pressed
      // Nothing spikes: a refinement whose compliance was not capped (max_compliance) lost its
      // proxy in the 1 Hz press with direct coupling and sent 10.7 N.
      EXPECT_LT(r.peak_force, 2.0) << dt << " s, " << hz << " Hz";
    }
}
