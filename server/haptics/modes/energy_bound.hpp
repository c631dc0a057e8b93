// The multirate path's energy bound: its local models (the step's linear response, the
// refined patch) render the cloth between global steps from a model that is not the cloth
// itself, and a model that lags the cloth can give the hand energy it never got. Over closed
// press cycles of the drum at a long global step the response model gives the user energy every
// cycle (the fade of a new step's change, response_contact.hpp, is a delay of up to one step;
// docs/haptic-loop.md, 'The multirate path is passive by construction'); on a real device that
// is the start of a limit cycle. So the rendered forces are bounded by
// energy, as in the energy-bounding algorithm (Kim and Ryu 2004), over all fingers together:
//
//   reserve  E_n = E_n-1 - sum_f F_f,n-1 . (x_f,n - x_f,n-1)
//
// is the energy the hand has put into the model since the touch began (F the force the device
// held over the interval, x its fingertip). Before a tick's forces are sent, the work they
// would do on the hand over the coming tick, P = sum_f F_f . v_f T, may not exceed E: where
// it would, the part of each force along its finger's motion is scaled back (the part across
// the motion, a stroke's normal force, does no work and is kept). So the energy the model
// returns is bounded by what it was given, over any interval of a touch, whatever the model
// does; the bound is only as late as one tick's change of velocity. When no finger touches the
// reserve is emptied: the next touch starts from nothing (conservative: the cloth may still
// ring, but it cannot push energy into a hand through a model that lags it).
//
// Across fingers, because the cloth carries energy from one finger to the other in a pinch.
// Real-time safe: no allocation, no lock.
#pragma once

#include <array>
#include <cstdint>

#include "haptics/sim/handoff.hpp"

namespace hapticloth::haptics {

struct EnergyBoundStats {
  std::uint64_t limited_ticks = 0;  ///< ticks on which some force was scaled back
  double withheld_j = 0.0;          ///< the work those forces would have done on the hand, J
  double largest_reserve_j = 0.0;   ///< the most the hand had put in at once, J
};

class EnergyBound {
 public:
  /// `period`: the haptic tick, s (the interval a force is held for).
  explicit EnergyBound(double period) : period_(period) { x_.fill(Vec3::Zero()); }

  /// The interval that ends now: `x` the fingertips (scene frame), `sent` the forces the device
  /// held over it (scene frame), `present` the fingers with a fresh sample. The reserve takes
  /// the hand's work; it empties when no finger touched over the interval.
  void account(const std::array<Vec3, kMaxFingers>& x, const std::array<Vec3, kMaxFingers>& sent,
               const std::array<bool, kMaxFingers>& present, int fingers) noexcept;
  /// This tick's forces on the fingers (`force`, scaled back in place) against the fingertips'
  /// velocities `v`: the work they would do on the hand over the coming tick stays within the
  /// reserve. `touching`: fingers in contact (the others' forces are zero and left alone).
  void limit(std::array<Vec3, kMaxFingers>& force, const std::array<Vec3, kMaxFingers>& v,
             const std::array<bool, kMaxFingers>& touching, int fingers) noexcept;

  double reserve() const { return reserve_; }
  const EnergyBoundStats& stats() const { return stats_; }

 private:
  double period_;
  double reserve_ = 0.0;
  bool touched_ = false;  // some finger was in contact on the last tick
  std::array<Vec3, kMaxFingers> x_{};
  std::array<bool, kMaxFingers> have_{};
  EnergyBoundStats stats_;
};

}  // namespace hapticloth::haptics
