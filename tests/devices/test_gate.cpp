// The safety gate every force passes (devices/hal/safety_gate).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "hal/safety_gate.hpp"
#include "support/alloc_counter.hpp"
#include "support/devices.hpp"

using namespace hapticloth::devices;
using hapticloth::test::two_fingers;

namespace {


// Runs the gate at 1 kHz with fresh state for n ticks from t, returning the last output.
DeviceCommand run(SafetyGate& g, double& t, int n, const DeviceCommand& in, bool fresh = true) {
  DeviceCommand out;
  for (int k = 0; k < n; ++k) {
    t += 0.001;
    g.apply(t, fresh ? t : -1.0, in, out);
  }
  return out;
}

// A gate that calls the state stale 5 ms after it was last fresh, and fades over 20 ms.
SafetyGate watchdog_gate() {
  GateConfig c;
  c.watchdog = 0.005;
  c.ramp_time = 0.02;
  return SafetyGate(two_fingers(), c);
}

// A watchdog gate that has passed force (fx, 0, 0) on finger 0 for 100 fresh ticks: `in` asks
// it, `out` is what the gate sent last, `t` the time of that tick.
struct SteadyGate {
  SafetyGate g = watchdog_gate();
  DeviceCommand in, out;
  double t = 0.0;
  explicit SteadyGate(double fx) {
    in.force[0] = Vec3(fx, 0, 0);
    out = run(g, t, 100, in);
  }
};

// n ticks of 1 ms from `out`, the state last fresh at `fresh` (NaN: fresh every tick), asking
// `in` while the gate is fresh and `stale_in` once it is stale: the largest change of finger
// 0's x force from a tick to the next, the first tick the gate was stale and the first that
// sent zero force (-1: none).
struct Fade {
  double max_jump = 0.0;
  int stale_at = -1, zero_at = -1;
};
Fade fade(SafetyGate& g, double& t, int n, double fresh, const DeviceCommand& in, const DeviceCommand& stale_in,
          DeviceCommand& out) {
  Fade f;
  double prev = out.force[0].x();
  for (int k = 1; k <= n; ++k) {
    t += 0.001;
    g.apply(t, std::isnan(fresh) ? t : fresh, g.stale() ? stale_in : in, out);
    if (g.stale() && f.stale_at < 0) f.stale_at = k;
    if (out.force[0].isZero(0.0) && f.zero_at < 0) f.zero_at = k;
    f.max_jump = std::max(f.max_jump, std::abs(out.force[0].x() - prev));
    prev = out.force[0].x();
  }
  return f;
}

}  // namespace

TEST(SafetyGate, NonFiniteForceBecomesZeroAndIsCounted) {
  SafetyGate g(two_fingers());
  double t = 0.0;
  DeviceCommand in;
  in.force[0] = Vec3(1, 0, 0);
  in.force[1] = Vec3(0.5, 0, 0);
  run(g, t, 100, in);  // ramped in
  in.force[0] = Vec3(std::numeric_limits<double>::quiet_NaN(), 0, 0);
  DeviceCommand out;
  t += 0.001;
  g.apply(t, t, in, out);
  EXPECT_TRUE(out.force[0].allFinite());
  EXPECT_TRUE(out.flags & kFlagFault);
  EXPECT_EQ(g.counters().non_finite, 1u);
  // The NaN finger's force heads to zero at the slew limit; the other finger is untouched.
  EXPECT_LT(out.force[0].x(), 1.0);
  EXPECT_NEAR(out.force[1].x(), 0.5, 1e-12);
  out = run(g, t, 10, in);
  EXPECT_EQ(out.force[0], Vec3::Zero());
  in.force[1] = Vec3(0, std::numeric_limits<double>::infinity(), 0);
  out = run(g, t, 10, in);
  EXPECT_TRUE(out.force[1].allFinite());
}

TEST(SafetyGate, ClampsToTheDeviceMaximum) {
  SafetyGate g(two_fingers(4.0));
  double t = 0.0;
  DeviceCommand in;
  in.force[0] = Vec3(30, 40, 0);  // 50 N
  const DeviceCommand out = run(g, t, 200, in);
  EXPECT_NEAR(out.force[0].norm(), 4.0, 1e-12);
  EXPECT_NEAR(out.force[0].x() / out.force[0].y(), 0.75, 1e-12);  // direction kept
  EXPECT_TRUE(out.flags & kFlagClamped);
  EXPECT_GT(g.counters().clamped, 0u);
  // A configured limit below the device's applies; one above it does not.
  GateConfig c;
  c.max_force = 2.0;
  EXPECT_DOUBLE_EQ(SafetyGate(two_fingers(4.0), c).max_force(), 2.0);
  c.max_force = 10.0;
  EXPECT_DOUBLE_EQ(SafetyGate(two_fingers(4.0), c).max_force(), 4.0);
}

TEST(SafetyGate, SlewRateLimitsASteps) {
  GateConfig c;
  c.slew_rate = 500.0;  // N/s: 0.5 N per 1 ms tick
  c.ramp_time = 1e-6;   // no fade: isolate the slew limit
  SafetyGate g(two_fingers(), c);
  double t = 0.0;
  DeviceCommand zero, step;
  run(g, t, 5, zero);
  step.force[0] = Vec3(0, 0, 3.0);
  DeviceCommand out;
  double prev = 0.0;
  for (int k = 1; k <= 10; ++k) {
    t += 0.001;
    g.apply(t, t, step, out);
    EXPECT_LE(out.force[0].z() - prev, 0.5 + 1e-12);
    prev = out.force[0].z();
  }
  EXPECT_NEAR(prev, 3.0, 1e-12);  // reached after 6 ticks
  EXPECT_GE(g.counters().slew_limited, 5u);
}

TEST(SafetyGate, StaleAfterWatchdogRampsToZeroAndRecoversSmoothly) {
  // Fresh state every tick: forces fade in over ramp_time.
  SteadyGate steady(2.0);
  auto& [g, in, out, t] = steady;
  EXPECT_FALSE(g.stale());
  EXPECT_NEAR(out.force[0].x(), 2.0, 1e-12);
  // State stops arriving at t_last: 5 ms later the gate is stale and the force ramps to zero.
  const Fade gone = fade(g, t, 60, t, in, in, out);
  // stale once the state is older than 5 ms (the 5th or 6th tick, by the clock's rounding)
  EXPECT_GE(gone.stale_at, 5);
  EXPECT_LE(gone.stale_at, 6);
  EXPECT_TRUE(out.flags & kFlagStale);
  EXPECT_EQ(out.force[0], Vec3::Zero());
  EXPECT_EQ(g.counters().stale_events, 1u);
  EXPECT_LE(gone.max_jump, 2.0 * 0.001 / 0.02 + 1e-12);  // a ramp, not a step
  // Fresh state again: the force comes back as a ramp.
  const Fade back = fade(g, t, 40, std::nan(""), in, in, out);
  EXPECT_FALSE(g.stale());
  EXPECT_NEAR(out.force[0].x(), 2.0, 1e-12);
  EXPECT_LE(back.max_jump, 2.0 * 0.001 / 0.02 + 1e-12);
}

// The haptic loop renders no force for a finger whose state is stale (its place is unknown): the
// gate fades out the force last asked while fresh over ramp_time (20 ms, as docs/devices.md
// says), and the slew limit (1000 N/s) does not cut it short. It used to fade the loop's zero,
// so 1.54 N went to 0 in 2 ms, at the slew limit.
TEST(SafetyGate, StaleStateFadesTheLastForceOverTheRampTime) {
  SteadyGate steady(1.5);
  auto& [g, in, out, t] = steady;
  ASSERT_NEAR(out.force[0].x(), 1.5, 1e-12);
  const DeviceCommand none;  // what the loop asks once the state is stale
  const Fade f = fade(g, t, 60, t, in, none, out);
  ASSERT_GT(f.stale_at, 0);
  EXPECT_NEAR(f.zero_at - f.stale_at, 19, 1);                 // 20 ms from the first stale tick
  EXPECT_LE(f.max_jump, 1.5 * 0.001 / 0.02 + 1e-12);         // 75 mN a tick: a ramp
  EXPECT_EQ(out.force[0], Vec3::Zero());
}

TEST(SafetyGate, NeverStateIsStaleAndApplyAllocatesNothing) {
  SafetyGate g(two_fingers());
  DeviceCommand in, out;
  in.force[0] = Vec3(1, 1, 1);
  hapticloth::test::AllocationGuard guard;
  for (int k = 0; k < 100; ++k) g.apply(0.001 * k, -1.0, in, out);
  EXPECT_EQ(guard.count(), 0u);
  EXPECT_TRUE(g.stale());
  EXPECT_EQ(out.force[0], Vec3::Zero());
  GateConfig bad;
  bad.slew_rate = -1;
  EXPECT_THROW(SafetyGate(two_fingers(), bad), std::invalid_argument);
}

// The tactile output passes the same gate: non-finite samples and pins become zero, values
// beyond the display's limits are clamped (counted and flagged), all fade with the forces when
// the device state goes stale, and a frame whose pin layout is not the display's sends no pins.
TEST(SafetyGate, TactileOutputIsLimitedAndFadesWithTheForces) {
  DeviceInfo info = two_fingers();
  info.tactile.vibration_rate = 4000;
  info.tactile.pin_rows = 2;
  info.tactile.pin_cols = 3;
  info.tactile.max_vibration = 50e-6;
  info.tactile.max_pin = 0.5e-3;
  SafetyGate g(info);
  double t = 0.0;
  run(g, t, 100, DeviceCommand{});  // fresh: gain 1
  TactileCommand in, out;
  TactileFrame& f = in.finger[0];
  f.samples = 4;
  f.vibration = {10e-6f, -80e-6f, std::numeric_limits<float>::quiet_NaN(), 49e-6f};
  f.rows = 2;
  f.cols = 3;
  f.pins = {0.1e-3f, -0.7e-3f, 0.0f, std::numeric_limits<float>::infinity(), 0.2e-3f, 0.4e-3f};
  g.apply_tactile(in, out);
  const TactileFrame& o = out.finger[0];
  ASSERT_EQ(o.samples, 4);
  EXPECT_FLOAT_EQ(o.vibration[0], 10e-6f);
  EXPECT_FLOAT_EQ(o.vibration[1], -50e-6f);
  EXPECT_EQ(o.vibration[2], 0.0f);
  EXPECT_FLOAT_EQ(o.vibration[3], 49e-6f);
  ASSERT_EQ(o.rows * o.cols, 6);
  EXPECT_FLOAT_EQ(o.pins[1], -0.5e-3f);
  EXPECT_EQ(o.pins[3], 0.0f);
  EXPECT_FLOAT_EQ(o.pins[5], 0.4e-3f);
  EXPECT_EQ(out.flags & (kTactileClamped | kTactileFault), kTactileClamped | kTactileFault);
  EXPECT_EQ(g.counters().tactile_clamped, 2u);
  EXPECT_EQ(g.counters().tactile_non_finite, 2u);
  EXPECT_EQ(out.finger[1].samples, 0);  // as its frame says
  in.finger[2].samples = 4;
  g.apply_tactile(in, out);
  EXPECT_EQ(out.finger[2].samples, 0);  // beyond the device's fingers: nothing
  in.finger[2].samples = 0;

  // Stale: the output fades as the forces do, to nothing.
  DeviceCommand force_out;
  double last = 1.0;
  for (int k = 0; k < 30; ++k) {
    t += 0.001;
    g.apply(t, -1.0, DeviceCommand{}, force_out);
    g.apply_tactile(in, out);
    EXPECT_LE(std::abs(out.finger[0].vibration[0]), last * 10e-6f + 1e-12f);
    last = g.gain();
    EXPECT_TRUE(out.flags & kTactileFaded);
  }
  EXPECT_EQ(out.finger[0].vibration[0], 0.0f);
  EXPECT_EQ(out.finger[0].pins[0], 0.0f);

  // A frame for another pin layout sends no pins; a display without vibration sends no samples.
  run(g, t, 100, DeviceCommand{});
  f.rows = 3;
  f.cols = 2;
  g.apply_tactile(in, out);
  EXPECT_EQ(out.finger[0].rows * out.finger[0].cols, 0);
  info.tactile.vibration_rate = 0;
  SafetyGate pins_only(info);
  pins_only.apply_tactile(in, out);
  EXPECT_EQ(out.finger[0].samples, 0);
}

// What a device declares of its display is checked, naming the field.
TEST(SafetyGate, RejectsATactileCapabilityItCannotDrive) {
  DeviceInfo info = two_fingers();
  info.tactile.vibration_rate = 4500;  // not a whole number of samples a tick at 1 kHz
  EXPECT_NE(validate(info).find("tactile.vibration_rate"), std::string::npos);
  info.tactile.vibration_rate = 17000;  // 17 samples a tick: more than a frame holds
  EXPECT_NE(validate(info).find("tactile.vibration_rate"), std::string::npos);
  info.tactile.vibration_rate = 4000;
  info.tactile.pin_rows = 9;
  info.tactile.pin_cols = 9;
  EXPECT_NE(validate(info).find("tactile.pins"), std::string::npos);
  info.tactile.pin_cols = 0;
  EXPECT_NE(validate(info).find("tactile.pins"), std::string::npos);
  info.tactile.pin_rows = 6;
  info.tactile.pin_cols = 4;
  info.tactile.max_vibration = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(validate(info).find("tactile.max_vibration"), std::string::npos);
  info.tactile.max_vibration = 1e-4;
  EXPECT_EQ(validate(info), "");
  info.tactile.pin_pitch = -1.0;
  EXPECT_THROW(SafetyGate{info}, std::invalid_argument);  // the gate takes no device it cannot check
}
