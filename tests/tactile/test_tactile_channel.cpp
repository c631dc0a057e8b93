// One fingertip's tactile output (server/tactile/tactile_channel) against the surface it slides
// over: the frequency v / lambda, the spectrum of a measured-style roughness trace by third-octave
// band, the amplitude's law, exact zeros, the pin frame, and stick-slip where the friction
// coefficient rises faster than the skin's spring can follow.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "cloth/surface.hpp"
#include "support/alloc_counter.hpp"
#include "tactile/spectrum.hpp"
#include "tactile/tactile_channel.hpp"

using namespace hapticloth;
using tactile::TactileChannel;
using tactile::TactileInput;
using tactile::TactileOutput;
using tactile::TactileParams;
using tactile::power_spectrum;

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kTick = 1e-3;

cloth::Surface weave(double weft_spacing, double warp_spacing, double miu, double mmd) {
  cloth::Surface s;
  s.weft = cloth::weave_profile(weft_spacing, 20e-6, cloth::WeaveShape::Sine);
  s.warp = cloth::weave_profile(warp_spacing, 15e-6, cloth::WeaveShape::Sine);
  s.miu = miu;
  s.mmd = mmd;
  s.normalize_friction();
  return s;
}

// A fingertip on the cloth with normal force `fn` (N) at material point (u, v) (m), its contact
// patch `patch_radius` (m) across.
TactileInput touching(double fn, double u, double v = 0.0, double patch_radius = 0.0) {
  return {.in_contact = true, .normal_force = fn, .u = u, .v = v, .patch_radius = patch_radius};
}

// The vibration of a stroke at `speed` (m/s) along direction (du, dv) for `seconds`, pressed
// with `fn` (N), from (0.3 mm, 0.2 mm), recorded after a lead-in of `lead` seconds (the skin's
// first stretch to the friction limit, a transient, left out).
std::vector<double> stroke(const cloth::Surface& s, double speed, double du, double dv, double seconds,
                           double fn, const TactileParams& p = {}, double lead = 0.0) {
  TactileChannel ch(s, p, kTick);
  TactileOutput out;
  std::vector<double> sig;
  const int ticks = static_cast<int>(std::lround(seconds / kTick)), skip = static_cast<int>(std::lround(lead / kTick));
  for (int i = 0; i <= ticks + skip; ++i) {
    const TactileInput in = touching(fn, 3e-4 + du * speed * i * kTick, 2e-4 + dv * speed * i * kTick, 0.004);
    ch.tick(in, out);
    if (i > skip) sig.insert(sig.end(), out.vibration.begin(), out.vibration.begin() + out.samples);
  }
  return sig;
}

double peak_hz(const std::vector<double>& sig, double rate) {
  const std::vector<double> p = power_spectrum(sig);
  size_t best = 1;
  for (size_t k = 1; k < p.size(); ++k)
    if (p[k] > p[best]) best = k;
  return static_cast<double>(best) * rate / static_cast<double>(sig.size());
}

double rms(const std::vector<double>& x) {
  double s = 0.0;
  for (double v : x) s += v * v;
  return std::sqrt(s / static_cast<double>(x.size()));
}

}  // namespace

// Frequency = sliding speed / spatial period (the standard mapping): strokes at 20-200 mm/s
// along the weft (0.5 mm yarns) and the warp (0.8 mm) peak at v / lambda of that direction,
// within 2% or one bin (1 Hz over a second), whichever is larger.
TEST(TactileChannel, FrequencyFollowsSpeedAlongEachDirection) {
  const cloth::Surface s = weave(0.5e-3, 0.8e-3, 0.3, 0.0);
  const TactileParams p;
  for (const double v : {0.02, 0.05, 0.1, 0.2})
    for (const int dir : {0, 1}) {
      const double lambda = dir == 0 ? 0.5e-3 : 0.8e-3;
      const std::vector<double> sig = stroke(s, v, dir == 0 ? 1.0 : 0.0, dir == 1 ? 1.0 : 0.0, 1.0, 0.4);
      const double expected = v / lambda, got = peak_hz(sig, p.rate);
      std::printf("%s at %3.0f mm/s: peak %6.1f Hz, v / lambda %6.1f Hz\n", dir == 0 ? "weft" : "warp",
                  v * 1e3, got, expected);
      EXPECT_NEAR(got, expected, std::max(0.02 * expected, 1.0)) << v << " m/s, direction " << dir;
    }
}

// The spectrum follows the surface: a measured-style roughness trace (a 0.625 mm weave on
// power-law roughness, 10 um steps over 100 mm) crossed at 100 mm/s; the energy in each
// third-octave band from 20 to 400 Hz is within 1.6 dB (a just-noticeable intensity step) of
// the trace's own spatial spectrum mapped by f = v k and scaled by the force gain (no friction
// variation here: the skin's stretch is constant while it slides).
TEST(TactileChannel, SpectrumFollowsTheSurfaceByThirdOctaveBand) {
  const double dx = 1e-5, length = 0.1, v = 0.1;
  const int n = static_cast<int>(std::lround(length / dx));
  std::mt19937 rng(7);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<double> d(n), h(n, 0.0);
  for (int i = 0; i < n; ++i) d[i] = i * dx;
  for (int m = 1; m <= 2000; ++m) {  // power-law roughness: amplitude ~ 1 / k up to 20 /mm
    const double k = m / length, a = 3e-6 / m * std::abs(g(rng)), ph = 2 * kPi * std::uniform_real_distribution<double>()(rng);
    for (int i = 0; i < n; ++i) h[i] += a * std::cos(2 * kPi * k * d[i] + ph);
  }
  for (int i = 0; i < n; ++i) h[i] += 10e-6 * std::sin(2 * kPi * d[i] / 0.625e-3);
  cloth::Surface s;
  s.weft = cloth::trace_profile(d, h);
  s.miu = 0.3;
  s.normalize_friction();
  const double fn = 0.3;
  TactileParams p;
  const std::vector<double> sig = stroke(s, v, 1.0, 0.0, s.weft.period() / v, fn, p, 0.05);
  const std::vector<double> ps = power_spectrum(sig);
  const std::vector<double> ph = power_spectrum(s.weft.samples());
  const double gain = fn / p.full_force;
  const double df_sig = p.rate / static_cast<double>(sig.size());
  const double df_trace = v / s.weft.period();  // Hz per spatial bin at speed v
  // Mean square per band (Parseval): the signal's against the trace's times gain^2.
  const std::vector<double> es = tactile::third_octave_bands(ps, df_sig), et = tactile::third_octave_bands(ph, df_trace);
  double worst = 0.0;
  for (size_t b = 0; b < es.size(); ++b) {
    const double db = 10.0 * std::log10(es[b] / (gain * gain * et[b]));
    std::printf("band %6.1f Hz: %+.2f dB\n", 20.0 * std::pow(2.0, static_cast<double>(b) / 3.0), db);
    worst = std::max(worst, std::abs(db));
  }
  EXPECT_LE(worst, 1.6);
}

// Amplitude follows the normal force, f_n / full_force below it, and saturates above; the
// output is exactly zero off contact and with the fingertip still (on a surface with friction
// variation, where the skin's stretch is not zero).
TEST(TactileChannel, AmplitudeFollowsNormalForceAndIsZeroOffContactOrStill) {
  const cloth::Surface s = weave(0.5e-3, 0.8e-3, 0.3, 0.0);
  // 25 yarns of 0.5 mm at 50 mm/s, after the skin's first stretch (MIU f_n / k_s, under 0.2 mm)
  // and the pulse it gives through the stretch's high-pass (8 ms: 0.1 s is 12 time constants)
  auto amplitude = [&](double fn) { return rms(stroke(s, 0.05, 1, 0, 0.25, fn, TactileParams{}, 0.1)); };
  const double a1 = amplitude(0.1), a2 = amplitude(0.2), a5 = amplitude(0.5), a10 = amplitude(1.0);
  EXPECT_GT(a1, 1e-6);
  EXPECT_NEAR(a2 / a1, 2.0, 1e-4);
  EXPECT_NEAR(a10 / a5, 1.0, 1e-4);

  const cloth::Surface rough = weave(0.5e-3, 0.8e-3, 0.3, 0.05);
  const std::vector<double> still = stroke(rough, 0.0, 1, 0, 0.2, 0.5);
  for (double x : still) ASSERT_EQ(x, 0.0);
  TactileChannel ch(rough, TactileParams{}, kTick);
  TactileOutput out;
  TactileInput in;
  in.normal_force = 0.5;  // pressing, but not in contact: nothing
  for (int i = 0; i < 10; ++i) {
    in.u = i * 1e-4;
    ch.tick(in, out);
    for (int k = 0; k < out.samples; ++k) ASSERT_EQ(out.vibration[k], 0.0f);
    for (int k = 0; k < out.rows * out.cols; ++k) ASSERT_EQ(out.pins[k], 0.0f);
  }
}

// Pins: each pin of the 6 x 4 array (2 mm pitch) within the contact patch is displaced by the
// surface height under it, the others not at all.
TEST(TactileChannel, PinFrameIsTheSurfaceUnderThePins) {
  const cloth::Surface s = weave(0.7e-3, 1.1e-3, 0.0, 0.0);  // no friction: the skin is at the fingertip
  TactileChannel ch(s, TactileParams{}, kTick);
  TactileOutput out;
  const TactileInput in = touching(0.3, 0.0123, -0.0042, 0.0045);
  ch.tick(in, out);
  ASSERT_EQ(out.rows, 6);
  ASSERT_EQ(out.cols, 4);
  int under = 0;
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 4; ++j) {
      const double du = (j - 1.5) * 0.002, dv = (i - 2.5) * 0.002;
      const bool inside = du * du + dv * dv <= in.patch_radius * in.patch_radius;
      under += inside;
      const float want = inside ? static_cast<float>(s.height(in.u + du, in.v + dv)) : 0.0f;
      EXPECT_EQ(out.pins[i * 4 + j], want) << i << "," << j;
    }
  EXPECT_EQ(under, 16);  // within 4.5 mm: |du| and |dv| <= 3 mm, every column and the 4 middle rows
}

// Stick-slip: the skin's spring k_s holds it against mu(u) f_n. Where mu rises along the path
// faster than k_s / f_n (mmd x max dphi/du x f_n > k_s), the skin sticks and then jumps ahead
// once per yarn; below that it slides smoothly. A 1 mm sine weave: max dphi/du = pi^2 / lambda.
TEST(TactileChannel, FrictionVariationGivesStickSlipOncePerYarn) {
  const double lambda = 1e-3, fn = 1.0, speed = 0.01, seconds = 1.0;
  const TactileParams p;  // k_s 1500 N/m
  auto jumps = [&](double mmd) {
    cloth::Surface s;
    s.weft = cloth::weave_profile(lambda, 20e-6, cloth::WeaveShape::Sine);
    s.miu = 0.6;
    s.mmd = mmd;
    s.normalize_friction();
    TactileChannel ch(s, p, kTick);
    TactileOutput out;
    int events = 0;
    double prev_ft = -1.0;
    for (int i = 0; i <= static_cast<int>(seconds / kTick); ++i) {
      const TactileInput in = touching(fn, speed * i * kTick);
      ch.tick(in, out);
      // A slip event: the spring's force drops by half the friction's mean deviation in a tick.
      // Sliding smoothly it follows mu down at most mmd f_n (pi^2 / lambda) v dt, 0.1 mmd f_n.
      if (prev_ft >= 0.0 && prev_ft - out.tangential_force > 0.5 * mmd * fn) ++events;
      prev_ft = out.tangential_force;
    }
    return events;
  };
  const double critical = p.skin_stiffness * lambda / (kPi * kPi * fn);  // mmd at the threshold
  const int smooth = jumps(0.5 * critical), sticky = jumps(2.0 * critical);
  const int yarns = static_cast<int>(speed * seconds / lambda);
  std::printf("mmd threshold %.3f: %d slip events below it, %d above (%d yarns crossed)\n", critical,
              smooth, sticky, yarns);
  EXPECT_EQ(smooth, 0);
  EXPECT_GE(sticky, yarns - 1);
  EXPECT_LE(sticky, yarns + 1);
}

// The haptic thread's rule: a tick allocates nothing.
TEST(TactileChannel, TickDoesNotAllocate) {
  const cloth::Surface s = weave(0.5e-3, 0.8e-3, 0.3, 0.05);
  TactileChannel ch(s, TactileParams{}, kTick);
  TactileOutput out;
  TactileInput in = touching(0.5, 0.0, 0.0, 0.004);
  test::AllocationGuard guard;
  for (int i = 0; i < 100; ++i) {
    in.u = i * 5e-5;
    ch.tick(in, out);
  }
  EXPECT_EQ(guard.count(), 0u);
}
