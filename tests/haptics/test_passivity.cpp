// The coupling's passivity observer and controller (server/haptics/loop/passivity.hpp), driven by a
// hand that follows an imposed motion: the energy the coupling gives the hand is measured from
// the forces held over each tick, independently of the observer.
#include <gtest/gtest.h>

#include <cmath>
#include <deque>

#include "haptics/loop/passivity.hpp"

using namespace hapticloth;
using haptics::Vec3;

namespace {

constexpr double kT = 1e-3;      // s, haptic period
constexpr double kK = 800.0;     // N/m, coupling spring
constexpr double kMaxF = 8.0;    // N

struct Outcome {
  double excess_j = 0.0;  // energy the hand got beyond what a lossless spring returns, J
  haptics::PassivityStats stats;
};

// The hand moves x(t) = A sin(w t) along x against a proxy fixed at the origin. The coupling
// renders F = -k x_c - c v with x_c the fingertip `delay` ticks ago (delay > 0: an active
// coupling, as a force held too long is). The energy the hand gets is sum F . dx over the held
// intervals; a lossless spring would give back -(U_end - U_0), so the excess over that is what
// the coupling created.
Outcome drive(int delay, double damping, bool control, double seconds = 2.0) {
  haptics::CouplingPassivity pc(kK, kMaxF);
  const double A = 0.01, w = 2.0 * M_PI * 3.0;
  std::deque<Vec3> past;
  Vec3 applied = Vec3::Zero(), x_prev = Vec3::Zero();
  double to_hand = 0.0;
  const long n = std::lround(seconds / kT);
  for (long i = 0; i <= n; ++i) {
    const double t = i * kT;
    const Vec3 x(A * std::sin(w * t), 0.0, 0.0), v(A * w * std::cos(w * t), 0.0, 0.0);
    if (i > 0) to_hand += applied.dot(x - x_prev);
    past.push_back(x);
    if (static_cast<int>(past.size()) > delay + 1) past.pop_front();
    const Vec3 xc = past.front();
    const Vec3 force = -kK * xc - damping * v;
    const Vec3 damp = pc.observe(0, kT, applied, x, Vec3::Zero(), v, force, -kK * xc, true);
    applied = force + (control ? damp : Vec3::Zero());
    x_prev = x;
  }
  const double u0 = 0.0, u1 = 0.5 * kK * x_prev.squaredNorm();
  return {to_hand + (u1 - u0), pc.stats()};
}

}  // namespace

// A spring held 5 ms too long creates energy every cycle (0.16 J in 2 s): the observer sees
// it, and the controller's damping takes it out again, so the hand gets less than 1 mJ (and
// less than 1% of it) beyond what a lossless spring returns.
TEST(Passivity, ActiveCouplingIsDetectedAndDissipated) {
  const Outcome off = drive(5, 0.0, false);
  const Outcome on = drive(5, 0.0, true);
  std::printf("delayed spring: excess %.3e J uncontrolled (deficit seen %.3e J), %.3e J "
              "controlled (%lu active ticks, %.3e J dissipated)\n",
              off.excess_j, off.stats.deepest_deficit_j, on.excess_j,
              static_cast<unsigned long>(on.stats.active_ticks), on.stats.dissipated_j);
  EXPECT_GT(off.excess_j, 5e-3);                             // active: millijoules a second
  EXPECT_NEAR(off.stats.deepest_deficit_j, off.excess_j, 0.05 * off.excess_j + 1e-4);
  EXPECT_GT(on.stats.active_ticks, 100u);
  // What is left is the deficit the controller is still dissipating (over 20 ms) at the end.
  EXPECT_LE(on.excess_j, std::min(1e-3, 0.01 * off.excess_j));
  EXPECT_GT(on.stats.dissipated_j, 0.5 * off.excess_j);
}

// On time with the coupling's damper above k T / 2 the coupling is passive: the controller
// never acts.
TEST(Passivity, PassiveCouplingIsLeftAlone) {
  const Outcome on = drive(0, 1.0, true);
  EXPECT_LE(on.excess_j, 0.0);
  EXPECT_EQ(on.stats.active_ticks, 0u);
  EXPECT_LT(on.stats.deepest_deficit_j, 1e-9);
}

// Without motion a damper dissipates nothing: the controller adds no force, and nothing is
// non-finite.
TEST(Passivity, NoMotionNoControl) {
  haptics::CouplingPassivity pc(kK, kMaxF);
  const Vec3 x(0.001, 0.0, 0.0);
  Vec3 f = Vec3::Zero();
  for (int i = 0; i < 10; ++i) {
    const Vec3 damp = pc.observe(0, kT, f, x, Vec3::Zero(), Vec3::Zero(), -kK * x, -kK * x, true);
    EXPECT_TRUE(damp.isZero());
    f = -kK * x;
  }
}

TEST(Passivity, RejectsBadParameters) {
  EXPECT_THROW(haptics::CouplingPassivity(0.0, kMaxF), std::invalid_argument);
  EXPECT_THROW(haptics::CouplingPassivity(kK, -1.0), std::invalid_argument);
  EXPECT_THROW(haptics::CouplingPassivity(kK, NAN), std::invalid_argument);
}
