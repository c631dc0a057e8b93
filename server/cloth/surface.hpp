// A fabric's surface, the input of tactile rendering (the paper's "tactile perception" half,
// section 1): its height along the weft and the warp, as Kawabata's KES-FB4 surface tester
// traces it (SMD, the mean deviation of that trace), and its friction coefficient's variation
// along the same path (MIU, the mean coefficient, and MMD, its mean deviation).
#pragma once

#include <string>
#include <vector>

namespace hapticloth::cloth {

/// One direction's height profile: one period sampled uniformly, zero mean, repeated along the
/// direction (a weave repeats every yarn; a measured trace is taken as one period of the
/// surface).
class SurfaceProfile {
 public:
  SurfaceProfile() = default;
  /// `height` (m) sampled every `spacing` (m) over one period; its mean is removed.
  SurfaceProfile(double spacing, std::vector<double> height);

  bool empty() const { return height_.empty(); }
  double spacing() const { return spacing_; }         ///< m between samples
  double period() const { return spacing_ * static_cast<double>(height_.size()); }  ///< m
  const std::vector<double>& samples() const { return height_; }
  /// Height at distance s (m) along the direction: linear between samples, periodic.
  double at(double s) const noexcept;
  /// The mean absolute height (m): KES-FB4's SMD for this trace.
  double mean_deviation() const;

 private:
  double spacing_ = 0.0;
  std::vector<double> height_;
};

/// The shape of a yarn across the weave: `sine`, a sinusoid; `yarn`, rounded crowns meeting in
/// cusps (|sin|, the section of round yarns lying side by side).
enum class WeaveShape { Sine, Yarn };
const char* to_string(WeaveShape s);

/// A weave's profile from its yarn spacing (m; 1 / threads per metre) and amplitude (m, half
/// the crown-to-valley height), sampled 64 times per yarn.
SurfaceProfile weave_profile(double yarn_spacing, double amplitude, WeaveShape shape);

/// A measured trace (distance m, increasing; height m) resampled at its smallest distance step,
/// as one period. Throws std::invalid_argument if it has under 8 points or distances that do
/// not increase.
SurfaceProfile trace_profile(const std::vector<double>& distance, const std::vector<double>& height);

/// How one direction's profile was given, so the material file can be written back.
struct SurfaceSource {
  std::string trace;  ///< CSV path as written in the material file, or empty for a weave
  double yarn_spacing = 0.0, amplitude = 0.0;
  WeaveShape shape = WeaveShape::Sine;
};

/// The surface in the cloth's material coordinates (u along the weft, v along the warp, m):
/// the heights of the two yarn systems add, h(u, v) = h_weft(u) + h_warp(v), and the friction
/// coefficient follows the same pattern, mu(u, v) = MIU + MMD phi(u, v), phi the height pattern
/// scaled to a mean absolute value of 1 (friction is highest on the yarn crowns, where the skin
/// touches).
struct Surface {
  SurfaceProfile weft, warp;
  SurfaceSource weft_source, warp_source;
  double miu = 0.0;  ///< mean friction coefficient (KES-FB4 MIU)
  double mmd = 0.0;  ///< mean deviation of the friction coefficient (KES-FB4 MMD)
  std::string source;  ///< where the figures come from

  bool present() const { return !weft.empty() || !warp.empty(); }
  double height(double u, double v) const noexcept {
    return (weft.empty() ? 0.0 : weft.at(u)) + (warp.empty() ? 0.0 : warp.at(v));
  }
  /// The friction coefficient at (u, v).
  double friction(double u, double v) const noexcept;
  /// d mu / d h, 1/m: how the friction coefficient follows the height, MMD / mean |h|.
  double friction_per_height() const noexcept { return mmd * phi_scale_; }
  /// Sets the friction pattern's scale from the profiles (call after setting them).
  void normalize_friction();

 private:
  double phi_scale_ = 0.0;  // 1 / mean |h(u, v)| over a period of each
};

}  // namespace hapticloth::cloth
