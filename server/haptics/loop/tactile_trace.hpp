// What each fingertip's skin was given over a run, kept to say after it whether the vibration
// followed the stroke: the longest slide of each finger, its speed over the fabric, the
// vibration's dominant frequency, and the weave's v / lambda along weft and warp. Recorded on
// the haptic thread into storage sized before the run (no allocation on the tick); analysed
// after the run.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "cloth/surface.hpp"
#include "haptics/observer.hpp"

namespace hapticloth::haptics {

/// One finger's stroke: of its stretches of ticks with texture, the one that moved furthest over
/// the fabric, its middle 80% analysed.
struct TactileStroke {
  int finger = 0;
  double start = 0.0, end = 0.0;       ///< s of session, the analysed stretch
  double speed_u = 0.0, speed_v = 0.0; ///< m/s over the fabric (material coordinates, median of 50 ms windows)
  double tip_speed = 0.0;              ///< m/s, the fingertip's mean speed in the scene
  double peak_hz = 0.0, bin_hz = 0.0;  ///< the vibration's dominant frequency, and the FFT bin
  double weft_hz = 0.0, warp_hz = 0.0; ///< |speed| / period along each direction (0 without one)
  double rms = 0.0;                    ///< m, the vibration's RMS over the stretch
  /// The direction whose v / lambda is nearer the peak, its frequency, and whether the peak is
  /// within 2% or one bin of it (the tactile channel's frequency criterion).
  const char* direction = "";
  double expected_hz = 0.0;
  bool matches = false;
  /// The fingertip carried the cloth along (its speed over the fabric under a fifth of its
  /// speed in the scene): a drag or a held pinch, with no weave frequency to follow.
  bool carried = false;
};

class TactileTrace final : public SessionObserver {
 public:
  /// Room for `ticks` ticks of `fingers` fingers with vibration blocks of up to `block` samples
  /// at `rate` Hz (ticks beyond it are counted, not kept).
  TactileTrace(const cloth::Surface& surface, int fingers, int block, double rate, double tick_s, long ticks);

  void on_tactile(const HapticReport& r, const TactileRendering& t, const devices::TactileCommand& c) noexcept override;

  /// Each finger's stroke (a stretch of texture of at least 0.25 s), if it has one.
  std::vector<TactileStroke> strokes() const;
  std::uint64_t ticks_kept() const { return kept_; }
  std::uint64_t ticks_lost() const { return lost_; }
  std::string to_text() const;
  nlohmann::json to_json() const;

 private:
  struct Tick {
    bool textured = false;
    double time = 0.0, u = 0.0, v = 0.0;
    Eigen::Vector3d tip = Eigen::Vector3d::Zero();
  };
  bool stroke(int f, TactileStroke& out) const;
  const Tick& at(long k, int f) const { return ticks_[static_cast<size_t>(k * fingers_ + f)]; }

  const cloth::Surface& surface_;
  int fingers_, block_;
  double rate_, tick_s_;
  long capacity_;
  std::vector<Tick> ticks_;
  std::vector<float> samples_;  // [tick][finger][block]
  std::uint64_t kept_ = 0, lost_ = 0;
};

}  // namespace hapticloth::haptics
