// hapticloth-bench tactile: strokes at 20, 50, 100 and 200 mm/s along the weft and the warp of
// every shipped material through one fingertip's tactile channel (server/tactile), pressed with
// 0.3 N: the vibration's dominant frequency against v / lambda, the energy in each third-octave
// band from 20 to 400 Hz against the surface model's prediction, and the output of a fingertip
// pressing and still (docs/tactile.md).
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <vector>

#include "accuracy.hpp"
#include "app/material_file.hpp"
#include "tactile/spectrum.hpp"
#include "tactile/tactile_channel.hpp"

namespace hapticloth::bench {

using nlohmann::json;

namespace {

constexpr double kTick = 1e-3;
constexpr double kNormalForce = 0.3;  // N: a light stroke, below the skin's full_force

// The vibration of a stroke at `speed` along direction `dir` (0 weft, 1 warp) for `seconds`,
// after a 50 ms lead-in (the skin's first stretch to the friction limit).
std::vector<double> stroke(const cloth::Surface& s, const tactile::TactileParams& p, int dir, double speed,
                           double seconds) {
  tactile::TactileChannel ch(s, p, kTick);
  tactile::TactileOutput out;
  std::vector<double> sig;
  const int skip = 50, ticks = static_cast<int>(std::lround(seconds / kTick));
  for (int i = 0; i <= skip + ticks; ++i) {
    tactile::TactileInput in;
    in.in_contact = true;
    in.normal_force = kNormalForce;
    in.u = 1e-4 + (dir == 0 ? speed * i * kTick : 0.0);
    in.v = 2e-4 + (dir == 1 ? speed * i * kTick : 0.0);
    in.patch_radius = 0.004;
    ch.tick(in, out);
    if (i > skip) sig.insert(sig.end(), out.vibration.begin(), out.vibration.begin() + out.samples);
  }
  return sig;
}

// The largest |dB| between two spectra's third-octave bands from 20 to 400 Hz (bins df_a and
// df_b Hz apart), over the bands where the prediction b holds energy.
double band_error_db(const std::vector<double>& a, double df_a, const std::vector<double>& b, double df_b) {
  const std::vector<double> ea = tactile::third_octave_bands(a, df_a), eb = tactile::third_octave_bands(b, df_b);
  double worst = 0.0;
  for (size_t k = 0; k < ea.size(); ++k)
    if (eb[k] > 1e-30) worst = std::max(worst, std::abs(10.0 * std::log10(std::max(ea[k], 1e-300) / eb[k])));
  return worst;
}

}  // namespace

json tactile(const TactileBenchOptions& o) {
  const tactile::TactileParams p;
  json cases = json::array();
  double still_rms = 0.0;
  std::vector<std::filesystem::path> files;
  for (const auto& e : std::filesystem::directory_iterator(o.source_dir + "/tools/materials"))
    if (e.path().extension() == ".toml") files.push_back(e.path());
  std::sort(files.begin(), files.end());
  for (const auto& file : files) {
    const cloth::Material m = app::load_material(file.string());
    if (!m.surface.present()) continue;
    for (int dir = 0; dir < 2; ++dir) {
      const cloth::SurfaceProfile& prof = dir == 0 ? m.surface.weft : m.surface.warp;
      if (prof.empty()) continue;
      const double lambda = prof.period();
      // The model's prediction: the profile's spectrum mapped by f = v k, times the force gain,
      // with the skin's stretch while it slides, (mu - MIU) f_n / k_s = (dmu/dh) h f_n / k_s, in
      // phase with the height before the stretch's high-pass: |1 + (dmu/dh) f_n / k_s HP(f)|^2.
      const double gain = std::min(kNormalForce / p.full_force, 1.0);
      const double stretch = m.surface.friction_per_height() * kNormalForce / p.skin_stiffness;
      const std::vector<double> pred = tactile::power_spectrum(prof.samples());
      for (const double v : {0.02, 0.05, 0.1, 0.2}) {
        const double period_s = lambda / v, seconds = std::ceil(0.5 / period_s) * period_s;
        const std::vector<double> sig = stroke(m.surface, p, dir, v, seconds);
        const std::vector<double> ps = tactile::power_spectrum(sig);
        const double df = p.rate / static_cast<double>(sig.size());
        std::vector<double> heard = pred;
        for (size_t k = 0; k < heard.size(); ++k)
          heard[k] *= gain * gain * std::norm(1.0 + stretch * p.stretch_highpass_response(static_cast<double>(k) * v / lambda));
        size_t best = 1;
        for (size_t k = 1; k < ps.size(); ++k)
          if (ps[k] > ps[best]) best = k;
        cases.push_back({{"material", m.name},
                         {"direction", dir == 0 ? "weft" : "warp"},
                         {"speed_m_s", v},
                         {"wavelength_m", lambda},
                         {"expected_hz", v / lambda},
                         {"peak_hz", static_cast<double>(best) * df},
                         {"bin_hz", df},
                         {"band_error_db_max", band_error_db(ps, df, heard, v / lambda)}});
      }
    }
    const std::vector<double> still = stroke(m.surface, p, 0, 0.0, 0.2);
    double s2 = 0.0;
    for (double x : still) s2 += x * x;
    still_rms = std::max(still_rms, std::sqrt(s2 / static_cast<double>(still.size())));
  }
  return {{"benchmark", "tactile"}, {"normal_force_n", kNormalForce}, {"rate_hz", p.rate},
          {"cases", cases}, {"still_rms", still_rms}};
}

}  // namespace hapticloth::bench
