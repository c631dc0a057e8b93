// The tactile half of the haptic loop (server/haptics/tactile_rendering, tactile_trace) end to
// end: a mock device with a tactile display strokes a woven drum and carries a pinched cloth,
// and what it records is checked against the weave: the vibration's dominant frequency is the
// speed over the fabric / the weave's period along the stroke, a fingertip carrying the cloth
// gets no weave frequency, a device without a display gets nothing and costs nothing.
#include <gtest/gtest.h>

#include <cmath>

#include "haptics/session.hpp"
#include "haptics/loop/tactile_trace.hpp"
#include "mock/mock_device.hpp"
#include "support/touch_scenes.hpp"
#include "tactile/spectrum.hpp"

using namespace hapticloth;
using haptics::Vec3;

namespace {

constexpr double kRadius = 0.008, kRate = 4000.0;

// Finger 0 pressed 3 mm into the drum in 0.3 s, held to 0.8 s, then sliding 4 cm along `dir`
// to 1.8 s (40 mm/s; 38.8 mm/s over a drum stretched 3%).
test::DrumRig woven_drum_stroke(const Vec3& dir, double friction, const devices::DeviceOptions& opt) {
  haptics::SessionConfig sc;
  sc.finger.friction = friction;
  const Vec3 start = -0.02 * dir + Vec3(0, 0, kRadius - 0.003);
  return test::DrumRig(test::with_weave(test::drum()),
                       test::one_finger({{0.0, start + Vec3(0, 0, 0.03)}, {0.3, start}, {0.8, start},
                                         {1.8, start + 0.04 * dir}}),
                       sc, test::sim_config(), opt);
}

const devices::MockDevice& mock(const test::DrumRig& rig) {
  return dynamic_cast<const devices::MockDevice&>(rig.dev.device());
}

// The dominant frequency (Hz) of finger f's recorded vibration between t0 and t1 s (tick k holds
// the samples of loop time k ms), and the spectrum's bin.
std::pair<double, double> peak(const devices::MockDevice& d, int f, double t0, double t1) {
  const std::vector<float>& rec = d.tactile_record().vibration[f];
  const auto a = static_cast<size_t>(t0 * kRate), b = std::min(rec.size(), static_cast<size_t>(t1 * kRate));
  const std::vector<double> x(rec.begin() + static_cast<long>(a), rec.begin() + static_cast<long>(b));
  const std::vector<double> p = tactile::power_spectrum(x);
  size_t best = 1;
  for (size_t k = 1; k < p.size(); ++k)
    if (p[k] > p[best]) best = k;
  const double bin = kRate / static_cast<double>(x.size());
  return {static_cast<double>(best) * bin, bin};
}

}  // namespace

// Along the weft and along the warp: the recorded vibration's dominant frequency is the speed
// over the fabric (38.8 mm/s: the 4 cm stroke over a drum stretched 3%) / that direction's
// period (0.5 mm weft, 0.8 mm warp), within 2% or a bin; the run's trace finds the same stroke.
TEST(TactileRendering, StrokeVibratesAtSpeedOverPeriodAlongEachDirection) {
  for (const bool weft : {true, false}) {
    devices::DeviceOptions opt = test::tactile_device_options();
    opt.tactile.pin_pitch = 1e-3;  // the stroke's contact patch is 1.3-1.4 mm in radius: 2 mm pins miss it
    test::DrumRig rig = woven_drum_stroke(weft ? Vec3::UnitX() : Vec3::UnitY(), 0.4, opt);
    haptics::TactileTrace trace(rig.model.material.surface, 2, 4, kRate, 1e-3, 2000);
    rig.session->add_observer(&trace);
    devices::TactileFrame pins;  // the pin frame half-way through the stroke, and the patch's radius
    double patch = 0.0;
    rig.session->run_stepped(1.8, 0.0, [&](const haptics::HapticLoop& h, const haptics::SimWorker& w) {
      if (std::abs(h.last_report().time - 1.3) < 1e-6) {
        pins = h.last_tactile().finger[0];
        patch = w.last_snapshot().proxy[0].patch_radius;
      }
    });
    const double lambda = weft ? 0.5e-3 : 0.8e-3, expected = 0.04 / 1.03 / lambda;
    const auto [hz, bin] = peak(mock(rig), 0, 1.0, 1.7);
    std::printf("%s: peak %.1f Hz against v / lambda %.1f Hz (bin %.1f Hz)\n", weft ? "weft" : "warp", hz, expected, bin);
    EXPECT_LE(std::abs(hz - expected), std::max(0.02 * expected, bin));
    const std::vector<haptics::TactileStroke> strokes = trace.strokes();
    ASSERT_EQ(strokes.size(), 1u);  // finger 1 never touches
    std::printf("trace: %.2f-%.2f s, %.2f mm/s over the fabric (%.2f, %.2f), tip %.2f mm/s, peak %.1f Hz\n", strokes[0].start,
                strokes[0].end, 1e3 * std::hypot(strokes[0].speed_u, strokes[0].speed_v), 1e3 * strokes[0].speed_u,
                1e3 * strokes[0].speed_v, 1e3 * strokes[0].tip_speed, strokes[0].peak_hz);
    EXPECT_STREQ(strokes[0].direction, weft ? "weft" : "warp");
    EXPECT_TRUE(strokes[0].matches);
    EXPECT_FALSE(strokes[0].carried);
    EXPECT_NEAR(std::hypot(strokes[0].speed_u, strokes[0].speed_v), 0.04 / 1.03, 0.05 * 0.04);
    // Pins: those within the contact patch follow the weave, the others are level.
    EXPECT_EQ(pins.rows, 6);
    EXPECT_EQ(pins.cols, 4);
    int raised = 0, inside = 0;
    for (int i = 0; i < 6; ++i)
      for (int j = 0; j < 4; ++j) {
        raised += pins.pins[i * 4 + j] != 0.0f;
        inside += std::hypot((j - 1.5) * 1e-3, (i - 2.5) * 1e-3) <= patch;
        EXPECT_LE(std::abs(pins.pins[i * 4 + j]), 20e-6);  // the two weaves' 10 um amplitudes
      }
    std::printf("patch radius %.2f mm: %d pins raised, %d within it\n", 1e3 * patch, raised, inside);
    EXPECT_GT(raised, 0);
    EXPECT_LE(raised, inside);
    // Held still in the drum (0.4-0.8 s): exactly nothing.
    const std::vector<float>& rec = mock(rig).tactile_record().vibration[0];
    for (size_t i = static_cast<size_t>(0.4 * kRate); i < static_cast<size_t>(0.8 * kRate); ++i) ASSERT_EQ(rec[i], 0.0f) << i;
  }
}

// A free cloth pinched from above and below and carried 2 cm sideways in 1 s: the fingertips
// move with the fabric, so they get no weave frequency. The trace calls it carried (under a fifth
// of the fingertip's speed over the fabric), and in the band where a slide at the fingertip's
// speed would put the weave (+-10% of v / lambda) there is under 5% of the amplitude such a
// slide gives at this force (the weave's RMS, 7.1 um, with the force gain at 1).
TEST(TactileRendering, CarriedClothGivesNoWeaveFrequency) {
  cloth::GridSpec g;
  g.width = g.height = 0.1;
  g.nx = g.ny = 12;
  g.origin = {-0.05, -0.05, 0.0};
  cloth::ClothModel model = test::with_weave(cloth::build_model(cloth::make_grid(g), test::denim(), {}));
  const cloth::ClothState start = cloth::rest_state(model);
  cloth::IntegratorConfig ic = test::sim_config();
  ic.gravity = Vec3(0, 0, -9.81);
  ic.air_damping = 0.5;
  const Vec3 at(0.0011, 0.0007, 0.0), up = Vec3::UnitZ(), side(0.02, 0, 0);
  devices::Trajectory tr(2);
  for (int f = 0; f < 2; ++f) {
    const Vec3 p = at + (f == 0 ? 1.0 : -1.0) * (kRadius - 0.002) * up;
    tr.add(f, 0.0, p);
    tr.add(f, 0.3, p);
    tr.add(f, 1.3, p + side);
  }
  test::TouchRig rig(std::move(model), std::move(tr), test::touch_session(0.6), ic, start, "cholmod", test::touch_pcg(),
                     test::tactile_device_options());
  haptics::TactileTrace trace(rig.model.material.surface, 2, 4, kRate, 1e-3, 1400);
  rig.session->add_observer(&trace);
  rig.session->run_stepped(1.3);
  const auto& d = dynamic_cast<const devices::MockDevice&>(rig.dev.device());
  for (int f = 0; f < 2; ++f) {
    const std::vector<float>& rec = d.tactile_record().vibration[f];
    ASSERT_GE(rec.size(), static_cast<size_t>(1.25 * kRate));
    const std::vector<double> x(rec.begin() + static_cast<long>(0.4 * kRate), rec.begin() + static_cast<long>(1.25 * kRate));
    const std::vector<double> p = tactile::power_spectrum(x);
    const double bin = kRate / static_cast<double>(x.size()), weave_hz = 0.02 / 0.5e-3;  // 40 Hz
    double band = 0.0;
    for (size_t k = 1; k < p.size(); ++k)
      if (std::abs(static_cast<double>(k) * bin - weave_hz) <= 0.1 * weave_hz) band += 2.0 * p[k];
    const double slide = 10e-6 / std::sqrt(2.0);
    std::printf("finger %d: weave band %.3f um RMS against %.1f um for a slide\n", f, 1e6 * std::sqrt(band), 1e6 * slide);
    EXPECT_LT(std::sqrt(band), 0.05 * slide);
    EXPECT_TRUE(rig.session->haptics().last_report().finger[f].in_contact);  // still carrying it
  }
  for (const haptics::TactileStroke& s : trace.strokes()) {
    std::printf("finger %d: %.2f mm/s over the fabric, tip %.1f mm/s\n", s.finger,
                1e3 * std::hypot(s.speed_u, s.speed_v), 1e3 * s.tip_speed);
    EXPECT_TRUE(s.carried);
  }
}

// A device that declares no tactile display gets no tactile output, and the loop has no tactile
// half (nothing computed); a display on a fabric without a [surface] is off, and says why.
TEST(TactileRendering, NothingForADeviceWithoutADisplayOrAFabricWithoutASurface) {
  {
    test::DrumRig rig = woven_drum_stroke(Vec3::UnitX(), 0.4, test::touch_device_options());
    rig.session->run_stepped(0.5);
    EXPECT_EQ(rig.session->haptics().tactile(), nullptr);
    EXPECT_EQ(mock(rig).tactile_record().frames, 0u);
    EXPECT_EQ(rig.session->report().tactile.rfind("off", 0), 0u);
  }
  haptics::SessionConfig sc;
  test::DrumRig bare(test::drum(), test::one_finger({{0.0, Vec3(0, 0, 0.05)}}), sc, test::sim_config(),
                     test::tactile_device_options());
  bare.session->run_stepped(0.1);
  EXPECT_EQ(bare.session->haptics().tactile(), nullptr);
  EXPECT_EQ(mock(bare).tactile_record().frames, 0u);
  EXPECT_NE(bare.session->report().tactile.find("no [surface]"), std::string::npos);
}
